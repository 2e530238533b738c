"""Shared helpers for the contact tests: evaluate the contact kernels on one env outside the solver."""
from __future__ import annotations

import numpy as np

from sim.contact.obstacles import contact_rows, find_candidates, node_forces
from sim.contact.world import (
    ObstacleGeometry,
    ObstacleWorld,
    SpecPoses,
    contact_data,
    contact_scratch,
    set_capsules,
    set_pose,
)
from sim.kernels.data import PARAMS_DTYPE, ContactReport

K = 1e6
DELTA = 5e-3
R_ROD = 0.05


def radii(rod_radius) -> np.ndarray:
    """The contact kernels' radius argument: (1,) for one radius, else one per edge."""
    return np.atleast_1d(np.asarray(rod_radius, dtype=np.float64))


def law(*, k=K, delta=DELTA, mu=0.0, nu=1e-2):
    """The contact law's parameters as the kernels read them: a Params record with only the contact fields set."""
    rec = np.zeros(1, dtype=PARAMS_DTYPE)
    rec[0]["contact_k"], rec[0]["contact_delta"], rec[0]["friction"], rec[0]["friction_nu"] = k, delta, mu, nu
    return rec[0]


class Obstacles:
    """Obstacles of ``envs`` envs outside a Simulator, through the production route: geometry, the State's pose
    arrays (at the spec poses), the world arrays derived from them and the kernels' ContactData
    (``sim.contact.world.contact_data``). Pose edits go through the same functions as ``Simulator.set_obstacle_pose``
    and ``set_capsules`` and re-derive the world arrays the ContactData holds."""

    def __init__(self, specs, n_nodes: int, *, rod_radius=R_ROD, envs: int = 1):
        self.geometry = ObstacleGeometry.from_specs(specs)
        self.poses = SpecPoses(self.geometry, envs)
        self.world = ObstacleWorld(self.geometry, envs).update(self.poses)
        self.cd = contact_data(self.geometry, self.world, self.poses,
                               contact_scratch(envs, n_nodes, self.geometry.count, rod_radius))

    def set_pose(self, i, position, orientation_wxyz=(1.0, 0.0, 0.0, 0.0), *, envs=None) -> None:
        set_pose(self.geometry, self.poses, i, position, orientation_wxyz, envs=envs)
        self.world.update(self.poses)

    def set_capsules(self, env_ids, starts, ends, radius, *, obstacle_ids=None) -> None:
        set_capsules(self.geometry, self.poses, env_ids, starts, ends, radius, obstacle_ids=obstacle_ids)
        self.world.update(self.poses)


def make_set(specs, n_nodes, *, rod_radius=R_ROD, envs=1):
    """(:class:`Obstacles`, its ContactData) for ``envs`` envs of a rod of ``n_nodes`` nodes."""
    obs = Obstacles(specs, n_nodes, rod_radius=rod_radius, envs=envs)
    return obs, obs.cd


def accumulate(cd, x, *, x_prev=None, dt=0.05, mu=0.0, nu=1e-2, friction_on=False, margin=5e-2,
               rod_radius=R_ROD, k=K, delta=DELTA, broadphase=True, e=0):
    """Return (energy [J], grad (N,3), hess (N-1,6,6)) of the contact at positions x (N, 3); ``rod_radius`` one
    value or one per edge."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    xp = x.copy() if x_prev is None else np.ascontiguousarray(x_prev, dtype=np.float64)
    if broadphase:
        find_candidates(e, cd, x, x, margin)
    g = np.zeros_like(x)
    h = np.zeros((x.shape[0] - 1, 6, 6))
    E = node_forces(e, law(k=k, delta=delta, mu=mu, nu=nu), cd, x, xp, dt, radii(rod_radius), friction_on, g, h)
    return E, g, h


def report(cd, x, *, x_prev=None, dt=0.05, mu=0.0, nu=1e-2, cap=64, rod_radius=R_ROD, e=0, B=1, k=K,
           delta=DELTA):
    x = np.ascontiguousarray(x, dtype=np.float64)
    xp = x.copy() if x_prev is None else np.ascontiguousarray(x_prev, dtype=np.float64)
    rows = ContactReport.zeros(B, cap)
    E = contact_rows(e, law(k=k, delta=delta, mu=mu, nu=nu), cd, x, xp, dt, radii(rod_radius), True, rows)
    return E, rows._asdict()


def dense_hessian(h, n):
    """Assemble (N-1, 6, 6) edge blocks into a dense (3N, 3N) matrix."""
    H = np.zeros((3 * n, 3 * n))
    for j in range(n - 1):
        H[3 * j:3 * j + 6, 3 * j:3 * j + 6] += h[j]
    return H


def fd_check(cd, x, *, eps=1e-7, **kw):
    """Max errors of grad vs FD(energy) and Hessian vs FD(grad), relative to the scale of each."""
    E, g, h = accumulate(cd, x, **kw)
    n = x.shape[0]
    H = dense_hessian(h, n)
    gn = np.zeros(3 * n)
    Hn = np.zeros((3 * n, 3 * n))
    for i in range(3 * n):
        xp = x.copy().reshape(-1)
        xm = x.copy().reshape(-1)
        xp[i] += eps
        xm[i] -= eps
        Ep, gp, _ = accumulate(cd, xp.reshape(n, 3), broadphase=False, **kw)
        Em, gm, _ = accumulate(cd, xm.reshape(n, 3), broadphase=False, **kw)
        gn[i] = (Ep - Em) / (2 * eps)
        Hn[:, i] = (gp - gm).reshape(-1) / (2 * eps)
    eg = np.abs(g.reshape(-1) - gn).max() / max(np.abs(gn).max(), 1e-9)
    eh = np.abs(H - Hn).max() / max(np.abs(Hn).max(), 1e-9)
    return E, eg, eh


def place_at_gap(cd, x, target, *, iters=3):
    """Translate the rod x (N, 3) along the contact normal until its smallest gap equals ``target`` [m]."""
    x = np.array(x, dtype=np.float64)
    for _ in range(iters):
        find_candidates(0, cd, x, x, 1.0)
        _, out = report(cd, x, x_prev=x, delta=1.0)
        if out["count"][0] == 0:
            raise AssertionError("place_at_gap: no contact within delta; start closer")
        i = int(np.argmin(out["gap"][0, :out["count"][0]]))
        x += (target - out["gap"][0, i]) * out["normal"][0, i]
    return x


FLOOR_NODES = 101  # a rod lying on the floor: one plane contact per node, more than the report's first capacity
FLOOR_DOC = {"sim": dict(dt=0.01, gravity=[0.0, 0.0, -9.8], damping=2.0, newton_tol=1e-8, newton_max_iter=30,
                         accept_unconverged=False, mode="3d"),
             "rod": dict(nodes=FLOOR_NODES, length=2.0, radius=0.01, density=1000.0, youngs_modulus=1e6,
                         poisson_ratio=0.5, start=[0.0, 0.0, 0.0098], direction=[1.0, 0.0, 0.0], clamp="none"),
             "contact": dict(stiffness=1e5, delta=1e-3, friction=0.5),
             "obstacle": [dict(type="plane", point=[0.0, 0.0, 0.0], normal=[0.0, 0.0, 1.0])]}
