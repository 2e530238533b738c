"""ObstacleSet: the runtime (per-env) obstacle arrays handed to the contact kernels (:mod:`sim.contact.obstacles`).

Static data (kinds, box half extents, mesh triangles + BVH in each mesh's local frame) is built once and shared,
read-only, by every copy. Per-env data (pose, capsule end points, radius, active flag) is part of the
:class:`sim.State` (``state.obstacles``) and changes in place through :meth:`ObstacleSet.set_pose`,
:meth:`ObstacleSet.set_capsules` and :meth:`ObstacleSet.set_active`; derived world arrays (centres, axes,
rotations, AABBs) are refreshed only for what changed. :meth:`ObstacleSet.copy` copies the per-env arrays.
The kernels' per-env work space (candidate lists) is a :class:`ContactScratch` owned by the Simulator;
:func:`contact_data` joins poses and scratch into the :class:`ContactData` the kernels read.
"""
from __future__ import annotations

import copy
from collections import namedtuple
from collections.abc import Sequence

import numpy as np

from .contact.mesh import build_bvh, cylinder_triangles, load_mesh_triangles
from .kinds import KIND_CODES
from .obstacles import (
    BoxSpec,
    CapsuleSpec,
    CylinderSpec,
    MeshSpec,
    ObstacleSpec,
    PlaneSpec,
    SphereSpec,
)
from .rotations import quat_to_matrix, quat_z_to

__all__ = ["ObstacleSet", "ContactData", "ContactScratch", "contact_scratch", "contact_data", "contact_radii",
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
_PER_ENV = ("position", "orientation", "local_a", "local_b", "radius", "active", "p0", "p1", "rot", "box")


def contact_scratch(envs: int, n_nodes: int, count: int, rod_radius) -> ContactScratch:
    """Work space of the contact kernels for ``envs`` envs of a rod of ``n_nodes`` nodes and ``count`` obstacles;
    ``rod_radius`` [m] (one value, or one per edge: the largest) inflates the broad phase."""
    B = int(envs)
    return ContactScratch(
        cand=np.zeros((B, max(int(n_nodes) * int(count), 1), 2), dtype=np.int64),
        cand_merge=np.zeros((B, 2 * max(int(n_nodes) * int(count), 1), 2), dtype=np.int64),
        cand_count=np.zeros(B, dtype=np.int64), broadphase_radius=np.array([float(np.max(rod_radius))]),
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


def contact_data(obs: "ObstacleSet", scratch: ContactScratch) -> ContactData:
    """The kernels' view of the poses in ``obs`` (a state's obstacles) with the work space ``scratch``."""
    return ContactData(obs.kind, obs.p0, obs.p1, obs.rot, obs.radius, obs.half, obs.mesh_root, obs.tri, obs.node_lo,
                       obs.node_hi, obs.node_child, obs.node_range, scratch.cand, scratch.cand_count, scratch.broadphase_radius,
                       obs.active, obs.box, scratch.scratch_f, scratch.scratch_m, scratch.scratch_i,
                       obs.friction, scratch.cand_merge)


class ObstacleSet:
    """Obstacles of one scene, replicated over ``envs`` environments.

    Attributes (per env, leading axis B): ``position`` (B, M, 3) [m], ``orientation`` (B, M, 4) wxyz,
    ``local_a``/``local_b`` (B, M, 3) [m] local geometry (capsule ends, sphere centre, plane point/normal),
    ``radius`` (B, M) [m], ``active`` (B, M) bool.
    """

    def __init__(self, specs: Sequence[ObstacleSpec] = (), *, envs: int = 1) -> None:
        self.specs = tuple(specs)
        M = len(self.specs)
        self.kind = np.array([KIND_CODES[s.type] for s in self.specs], dtype=np.int64)  # type: ignore
        self.half = np.zeros((M, 3))
        # per-obstacle Coulomb μ; -1 = the [contact] friction (the kernels' scalar μ)
        self.friction = np.array([-1.0 if s.friction is None else float(s.friction) for s in self.specs])
        self.mesh_root = -np.ones(M, dtype=np.int64)
        self._mesh_box = np.zeros((M, 2, 3))  # local AABB of each mesh
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
                self._mesh_box[i, 0] = np.concatenate(lo)[root]
                self._mesh_box[i, 1] = np.concatenate(hi)[root]
        self.tri = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.node_lo = np.concatenate(lo) if lo else np.zeros((0, 3))
        self.node_hi = np.concatenate(hi) if hi else np.zeros((0, 3))
        self.node_child = np.concatenate(ch).astype(np.int64) if ch else np.zeros((0, 2), dtype=np.int64)
        self.node_range = np.concatenate(rg).astype(np.int64) if rg else np.zeros((0, 2), dtype=np.int64)
        # spec (env-independent) initial per-obstacle state
        self._pos0 = np.zeros((M, 3))
        self._quat0 = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (M, 1))
        self._la0 = np.zeros((M, 3))
        self._lb0 = np.zeros((M, 3))
        self._rad0 = np.zeros(M)
        for i, s in enumerate(self.specs):
            if isinstance(s, PlaneSpec):
                self._la0[i], self._lb0[i] = s.point, s.normal
            elif isinstance(s, SphereSpec):
                self._la0[i], self._rad0[i] = s.center, s.radius
            elif isinstance(s, CapsuleSpec):
                self._la0[i], self._lb0[i], self._rad0[i] = s.start, s.end, s.radius
            elif isinstance(s, (BoxSpec, MeshSpec)):
                self._pos0[i], self._quat0[i] = s.position, s.orientation
            elif isinstance(s, CylinderSpec):  # the prism's frame: centre at the axis midpoint, z along the axis
                a, b = np.asarray(s.start, np.float64), np.asarray(s.end, np.float64)
                self._pos0[i], self._quat0[i] = 0.5 * (a + b), quat_z_to(b - a)
        self._n_nodes = 0
        self._rod_radius = 0.0
        self._kd: ContactData | None = None
        self._alloc(envs)

    def copy(self) -> "ObstacleSet":
        """A copy with its own per-env arrays (poses, capsules, active flags, world arrays); the static data
        (kinds, meshes, BVHs) is shared."""
        new = copy.copy(self)
        new._kd = None
        for name in _PER_ENV:
            setattr(new, name, getattr(self, name).copy())
        return new

    def __deepcopy__(self, memo) -> "ObstacleSet":  # snapshots copy poses, never the shared meshes
        return self.copy()

    @classmethod
    def from_specs(cls, specs: Sequence[ObstacleSpec], *, envs: int = 1) -> "ObstacleSet":
        return cls(specs, envs=envs)

    def for_envs(self, envs: int, *, n_nodes: int | None = None,
                 rod_radius: float | np.ndarray | None = None) -> "ObstacleSet":
        """A new ObstacleSet for ``envs`` environments sharing this one's static data (meshes, BVHs), with
        its own per-env poses at the spec values. Use one per Simulator."""
        new = copy.copy(self)
        new._kd = None
        new._alloc(int(envs))
        if n_nodes is not None or rod_radius is not None:
            new.kernel_data(n_nodes=n_nodes, rod_radius=rod_radius)
        return new

    # ------------------------------------------------------------------ sizes
    @property
    def count(self) -> int:
        """Number of obstacles M (the solver skips every contact call when 0)."""
        return len(self.specs)

    @property
    def envs(self) -> int:
        return self.position.shape[0]

    @property
    def report_capacity(self) -> int:
        """Capacity C of the per-env contact rows in StepStats (0 without obstacles)."""
        return REPORT_CAPACITY if self.count else 0

    @property
    def capsule_ids(self) -> np.ndarray:
        """Indices of the capsule obstacles, in scene order."""
        return np.flatnonzero(self.kind == KIND_CODES["capsule"])

    def _alloc(self, envs: int) -> None:
        B, M = int(envs), self.count
        self.position = np.broadcast_to(self._pos0, (B, M, 3)).copy()
        self.orientation = np.broadcast_to(self._quat0, (B, M, 4)).copy()
        self.local_a = np.broadcast_to(self._la0, (B, M, 3)).copy()
        self.local_b = np.broadcast_to(self._lb0, (B, M, 3)).copy()
        self.radius = np.broadcast_to(self._rad0, (B, M)).copy()
        self.active = np.ones((B, M), dtype=np.bool_)
        self.p0 = np.zeros((B, M, 3))
        self.p1 = np.zeros((B, M, 3))
        self.rot = np.zeros((B, M, 3, 3))
        self.box = np.zeros((B, M, 2, 3))
        self._kd = None
        self._refresh(np.arange(B), np.arange(M))

    # ------------------------------------------------------------------ world arrays
    def _refresh(self, envs: np.ndarray, obs: np.ndarray) -> None:
        if len(envs) == 0 or len(obs) == 0:
            return
        ix = np.ix_(envs, obs)
        R = quat_to_matrix(self.orientation[ix])  # (k, m, 3, 3)
        pos = self.position[ix]
        la = np.einsum("kmij,kmj->kmi", R, self.local_a[ix]) + pos
        lb_rot = np.einsum("kmij,kmj->kmi", R, self.local_b[ix])
        kind = self.kind[obs][None, :, None]
        rad = self.radius[ix][..., None]
        p1 = np.where(kind == KIND_CODES["plane"], lb_rot, lb_rot + pos)
        self.p0[ix] = la
        self.p1[ix] = p1
        self.rot[ix] = R
        lo = np.minimum(la, p1) - rad
        hi = np.maximum(la, p1) + rad
        sph = kind == KIND_CODES["sphere"]
        lo = np.where(sph, la - rad, lo)
        hi = np.where(sph, la + rad, hi)
        for code, getbox in ((KIND_CODES["box"], None), (KIND_CODES["mesh"], None)):
            sel = self.kind[obs] == code
            if not np.any(sel):
                continue
            if code == KIND_CODES["box"]:
                c_loc = np.zeros((sel.sum(), 3))
                h_loc = self.half[obs][sel]
            else:
                mb = self._mesh_box[obs][sel]
                c_loc = 0.5 * (mb[:, 0] + mb[:, 1])
                h_loc = 0.5 * (mb[:, 1] - mb[:, 0])
            Rs = R[:, sel]
            c = np.einsum("kmij,mj->kmi", Rs, c_loc) + pos[:, sel]
            ext = np.einsum("kmij,mj->kmi", np.abs(Rs), h_loc)
            lo[:, sel] = c - ext
            hi[:, sel] = c + ext
        pl = (self.kind[obs] == KIND_CODES["plane"])
        lo[:, pl] = -np.inf
        hi[:, pl] = np.inf
        self.box[ix + (0,)] = lo
        self.box[ix + (1,)] = hi

    def _env_ids(self, envs) -> np.ndarray:
        if envs is None:
            return np.arange(self.envs)
        e = np.asarray(envs)
        if e.dtype == np.bool_:
            if e.shape != (self.envs,):
                raise ValueError(f"env mask must have shape ({self.envs},), got {e.shape}")
            return np.flatnonzero(e)
        e = np.atleast_1d(e).astype(np.int64)
        if e.size and (e.min() < 0 or e.max() >= self.envs):
            raise ValueError(f"env ids out of range [0, {self.envs}): {e}")
        return e

    def _obstacle_id(self, i: int) -> int:
        if not 0 <= int(i) < self.count:
            raise IndexError(f"obstacle index {i} out of range [0, {self.count})")
        return int(i)

    # ------------------------------------------------------------------ editing
    def set_pose(self, i: int, position, orientation_wxyz=(1.0, 0.0, 0.0, 0.0), *, envs=None) -> None:
        """Set obstacle ``i``'s pose: ``position`` (3,) or (k, 3) [m], ``orientation_wxyz`` (4,) or (k, 4)."""
        i = self._obstacle_id(i)
        ids = self._env_ids(envs)
        p = np.broadcast_to(np.asarray(position, dtype=np.float64), (len(ids), 3))
        q = np.broadcast_to(np.asarray(orientation_wxyz, dtype=np.float64), (len(ids), 4))
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))) or np.any(np.linalg.norm(q, axis=1) < 1e-12):
            raise ValueError("set_pose: position/orientation must be finite and the quaternion non-zero")
        self.position[ids, i] = p
        self.orientation[ids, i] = q / np.linalg.norm(q, axis=1, keepdims=True)
        self._refresh(ids, np.array([i]))

    def set_capsules(self, env_ids, starts, ends, radius, *, obstacle_ids=None) -> None:
        """Re-place capsules per env (vectorised, e.g. at reset).

        ``starts``/``ends`` (k, m, 3) [m] world end points for envs ``env_ids`` (k,) and the m capsule
        obstacles ``obstacle_ids`` (default: all capsules in scene order); ``radius`` scalar, (m,) or
        (k, m) [m]. The capsules' poses are reset to identity for those envs.
        """
        ids = self._env_ids(env_ids)
        obs = self.capsule_ids if obstacle_ids is None else np.asarray(obstacle_ids, dtype=np.int64)
        if np.any(self.kind[obs] != KIND_CODES["capsule"]):
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
        self.local_a[ix] = a
        self.local_b[ix] = b
        self.radius[ix] = rad
        self.position[ix] = 0.0
        self.orientation[ix] = np.array([1.0, 0.0, 0.0, 0.0])
        self._refresh(ids, obs)

    def set_active(self, i: int, active: bool, *, envs=None) -> None:
        """Enable/disable obstacle ``i`` in the given envs (disabled obstacles cost nothing)."""
        self.active[self._env_ids(envs), self._obstacle_id(i)] = bool(active)

    def reset_envs(self, envs=None) -> None:
        """Restore the spec poses/geometry of the given envs."""
        ids = self._env_ids(envs)
        self.position[ids] = self._pos0
        self.orientation[ids] = self._quat0
        self.local_a[ids] = self._la0
        self.local_b[ids] = self._lb0
        self.radius[ids] = self._rad0
        self.active[ids] = True
        self._refresh(ids, np.arange(self.count))

    def effective_friction(self, default: float) -> np.ndarray:
        """(M,) Coulomb μ of each obstacle: its own ``friction`` or ``default`` (the [contact] friction)."""
        return np.where(self.friction >= 0.0, self.friction, float(default))

    # ------------------------------------------------------------------ kernel data
    def kernel_data(self, envs: int | None = None, *, n_nodes: int | None = None,
                    rod_radius: float | np.ndarray | None = None) -> ContactData:
        """The tuple of arrays read by :mod:`sim.contact.obstacles` (layout documented there).

        Re-allocates per-env arrays only if ``envs`` changes (then poses return to the spec); otherwise
        the same arrays are returned, so later ``set_pose``/``set_capsules`` calls are seen by the solver.
        ``n_nodes`` sizes the candidate buffers (B, n_nodes * M, 2); ``rod_radius`` [m]: the rod's radius, or
        one per edge (see :func:`contact_scratch`).
        """
        if envs is not None and int(envs) != self.envs:
            self._alloc(int(envs))
        rr = rod_radius if rod_radius is not None else self._rod_radius
        n = int(n_nodes) if n_nodes is not None else max(self._n_nodes, 64)
        if self._kd is None or n != self._n_nodes or not np.array_equal(rr, self._rod_radius):
            self._n_nodes, self._rod_radius = n, rr
            self._kd = contact_data(self, contact_scratch(self.envs, n, self.count, rr))
        return self._kd
