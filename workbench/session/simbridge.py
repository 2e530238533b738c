"""The only place the workbench touches the ``sim`` API (single env, B = 1).

``LiveSim`` owns spec, model, simulator, state and control, steps them, copies them for
snapshots and turns them into a drawable :class:`workbench.session.frame.Frame`.
"""
from __future__ import annotations

import copy
import dataclasses
import time
from pathlib import Path

import numpy as np

from sim import Simulator, build_model, load_scene
from sim.analysis import internal_loads
from sim.contact import OBSTACLE_ARRAYS, node_radii
from sim.support.assets import asset_path
from workbench.session.frame import Frame, curvature_magnitude, edge_strain
from workbench.session.teleop import control_points


class ActionRefused(RuntimeError):
    """An action the session cannot take now (e.g. editing a task's scene while its policy runs): the page
    shows the message in the status line; nothing is logged."""


def copy_struct(obj):
    """Deep copy of a State/Control-like struct of numpy arrays (dataclass or plain object)."""
    return copy.deepcopy(obj)


def assign_struct(dst, src) -> None:
    """Copy every array field of ``src`` into ``dst`` in place (keeps the identity of ``dst``)."""
    fields = ([f.name for f in dataclasses.fields(dst)] if dataclasses.is_dataclass(dst)
              else list(vars(dst)))
    for name in fields:
        a, b = getattr(dst, name), getattr(src, name)
        if isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape:
            a[...] = b
        else:
            setattr(dst, name, copy.deepcopy(b))


def obstacle_arrays(state) -> dict[str, np.ndarray]:
    """Copies of ``state``'s obstacle poses (:data:`sim.contact.world.OBSTACLE_ARRAYS`)."""
    return {name: getattr(state, name).copy() for name in OBSTACLE_ARRAYS}


def put_obstacle_arrays(state, arrays: dict[str, np.ndarray]) -> None:
    """Give ``state`` the obstacle poses ``arrays`` (from :func:`obstacle_arrays`; the scene's obstacles may differ
    in number from the ones the state had)."""
    for name, a in arrays.items():
        setattr(state, name, a)


class LiveSim:
    """One live rod (B = 1) built from a scene.

    Args:
        spec: a ``SceneSpec`` (``sim.load_scene``).
        gravity: keep the scene's gravity (True) or switch it off (False).
    """

    def __init__(self, spec, *, gravity: bool = True):
        self.base_spec = spec
        self.gravity = gravity
        self._build(keep_state=False)

    @classmethod
    def adopt(cls, owner) -> "LiveSim":
        """Wrap an existing simulator (a task core's ``sim``, ``model``, ``state``, ``ctrl``, B = 1)."""
        self = cls.__new__(cls)
        self.owner = owner
        self.base_spec = getattr(owner, "scene_spec", None) or getattr(owner.model, "spec", None)
        self.gravity = True
        self.model, self.sim = owner.model, owner.sim
        self.state, self.ctrl = owner.state, owner.ctrl
        self.rest_ctrl = owner.sim.make_control()
        self.rest_length = np.asarray(self.model.rest_edge_length, dtype=np.float64)  # (a pre-stretched rod: shorter)
        self.last_stats = None
        self.step_time = 0.0
        return self

    # ---------------------------------------------------------------- building
    def _spec_for_build(self):
        spec = self.base_spec
        if not self.gravity:
            spec = _replace_gravity(spec, (0.0, 0.0, 0.0))
        return spec

    owner = None  # a task core whose simulator this wraps (policy mode), else None

    def current_spec(self):
        """The scene the live rod runs now (gravity as switched)."""
        return self._spec_for_build()

    def _build(self, *, keep_state: bool) -> None:
        if self.owner is not None:
            raise ActionRefused("this simulator belongs to a task; stop the policy to edit the scene")
        old_state = getattr(self, "state", None) if keep_state else None
        old_ctrl = getattr(self, "ctrl", None) if keep_state else None
        self.model = build_model(self._spec_for_build())
        self.sim = Simulator(self.model, envs=1)
        self.state = self.sim.reset()
        self.ctrl = self.sim.make_control()
        self.rest_ctrl = copy_struct(self.ctrl)
        self.rest_length = np.asarray(self.model.rest_edge_length, dtype=np.float64)  # (a pre-stretched rod: shorter)
        if old_state is not None:
            obstacles = obstacle_arrays(self.state)  # the new scene's obstacles, not the old state's
            assign_struct(self.state, old_state)
            assign_struct(self.ctrl, old_ctrl)
            put_obstacle_arrays(self.state, obstacles)
        self.last_stats = None
        self.step_time = 0.0

    def set_gravity(self, on: bool) -> None:
        """Switch gravity on/off; rebuilds the model, keeps the current state and control."""
        if on != self.gravity:
            self.gravity = on
            self._build(keep_state=True)

    def set_spec(self, spec, *, keep_state: bool = True) -> None:
        """Replace the scene (e.g. after adding or deleting an obstacle) and rebuild."""
        self.base_spec = spec
        self._build(keep_state=keep_state)

    # ---------------------------------------------------------------- stepping
    @property
    def dt(self) -> float:
        return float(self.model.dt)

    @property
    def n_nodes(self) -> int:
        return int(self.state.node_pos.shape[1])

    @property
    def rod_radius(self) -> float:
        """The rod's largest contact radius [m] (the tube drawn for one radius)."""
        return float(self.model.radius_max)

    @property
    def node_radius(self) -> np.ndarray | None:
        """(N,) radius at each node [m] of a non-uniform rod (the larger of a node's two edges', as in contact);
        None when the rod has one radius."""
        er = getattr(self.model, "edge_radius", None)
        if er is None or np.all(er == er[0]):
            return None
        return node_radii(er)

    @property
    def rod_offsets(self) -> np.ndarray | None:
        """(R+1,) where each rod's nodes start (then N) when the scene has several rods, else None."""
        off = getattr(self.model, "rod_node_offsets", None)
        return None if off is None or len(off) <= 2 else np.asarray(off, np.int64)

    def reset(self) -> None:
        if self.owner is not None:  # the task resets its own simulator
            self.last_stats = None
            return
        new = self.sim.reset()
        put_obstacle_arrays(new, obstacle_arrays(self.state))  # obstacles the user placed stay where they are
        assign_struct(self.state, new)
        assign_struct(self.ctrl, self.sim.make_control())
        self.last_stats = None

    def step(self, run=None):
        """One sim step, timed, its stats kept. ``run``: a call that makes the step and returns its StepStats
        (policy mode: the task core's ``sim_step``, so the step is the episode's); default ``sim.step``."""
        t0 = time.perf_counter()
        self.last_stats = self.sim.step(self.state, self.ctrl) if run is None else run()
        self.step_time = time.perf_counter() - t0
        return self.last_stats

    def step_scalars(self) -> dict[str, float]:
        """Solver/contact values of the last step: newton_iters, converged and failed (1 or 0), contact_count,
        contact_force (largest normal contact force [N]), max_penetration [m], contact_dropped (contacts not listed in
        the report) and contact_net_force (|total contact force on the rods| [N], every contact counted; a crossing of
        two rods adds nothing: they push each other equally and oppositely) (empty before the first step)."""
        st = self.last_stats
        if st is None:
            return {}
        out = {"newton_iters": float(np.asarray(st.newton_iters)[0]),
               "converged": float(bool(np.asarray(st.converged)[0])), "failed": float(bool(np.asarray(st.failed)[0]))}
        if hasattr(st, "max_penetration"):
            out["max_penetration"] = float(np.asarray(st.max_penetration)[0])
        k = int(np.asarray(st.contact_count)[0]) if hasattr(st, "contact_count") else 0
        out["contact_count"] = float(k)
        out["contact_force"] = float(np.abs(np.asarray(st.contact_normal_force)[0, :k]).max()) if k else 0.0
        dropped = np.asarray(getattr(st, "contact_dropped", ()))
        if dropped.size:  # contacts the report did not list (the Simulator grows it for the next steps)
            out["contact_dropped"] = float(dropped[0])
        net = np.asarray(getattr(st, "contact_force", ()))
        if net.size:  # |the total contact force on the rods|, every contact counted, listed or not
            out["contact_net_force"] = float(np.linalg.norm(net[0]))
        return out

    @property
    def tip(self) -> np.ndarray:
        return np.asarray(self.state.node_pos[0, -1], dtype=np.float64).copy()

    def tip_frame(self) -> np.ndarray | None:
        """(3, 3) the tip edge's material frame, columns (m1, m2, t); None in 2-D (no frame to turn)."""
        if self.model.mode != "3d":
            return None
        m1, m2, t = self.sim.material_frames(self.state)
        return np.stack([m1[0, -1], m2[0, -1], t[0, -1]], axis=-1)

    # ---------------------------------------------------------------- snapshots
    def snapshot(self) -> tuple:
        return copy_struct(self.state), copy_struct(self.ctrl)

    def restore(self, snap: tuple) -> None:
        """Back to a snapshot. A task's obstacles (re-placed per episode) come back with its state; obstacles the
        user placed in teleop are scene edits and stay where they are."""
        keep = obstacle_arrays(self.state) if self.owner is None else None
        assign_struct(self.state, snap[0])
        assign_struct(self.ctrl, snap[1])
        if keep is not None:
            put_obstacle_arrays(self.state, keep)

    # ---------------------------------------------------------------- drawing
    def frame(self, *, targets: np.ndarray | None = None, scalars: dict | None = None) -> Frame:
        x = np.asarray(self.state.node_pos[0], dtype=np.float64)
        mf = self.sim.material_frames(self.state)  # an error here is a simulator defect: it is not hidden
        m1, m2 = np.asarray(mf[0][0]), np.asarray(mf[1][0])
        cp, cf, cn, cfn = contacts_from_stats(self.last_stats)
        rows = contact_rows(self.last_stats)
        loads = internal_loads(self.sim.model, x, m1, m2, self.ctrl.kappa_bar[0], self.ctrl.tau_bar[0])
        sc = {**self.step_scalars(), **(scalars or {})}
        kb = getattr(self.ctrl, "kappa_bar", None)
        off = self.rod_offsets
        curv = curvature_magnitude(x, off)  # each rod's end nodes bend nothing (the joint edge is no rod's)
        return Frame(node_pos=x.copy(), rod_radius=self.rod_radius, node_radius=self.node_radius, m1=m1, m2=m2,
                     kappa_bar=None if kb is None else np.asarray(kb[0], dtype=np.float64).copy(),
                     node_curvature=curv, edge_strain=edge_strain(x, self.rest_length),
                     contact_points=cp, contact_forces=cf, contact_normals=cn, contact_normal_force=cfn,
                     targets=np.zeros((0, 3)) if targets is None else np.asarray(targets).reshape(-1, 3),
                     time=float(np.asarray(self.state.time)[0]), scalars=sc, rod_offsets=off,
                     node_vel=np.asarray(self.state.node_vel[0], dtype=np.float64).copy(),
                     edge_axial_force=loads.axial, node_moment=np.column_stack([loads.bending, loads.twisting]),
                     contact_edge=rows["edge"], contact_gap=rows["gap"], contact_obstacle=rows["obstacle"],
                     contact_partner_edge=rows["partner_edge"])


def contacts_from_stats(st, env: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Active contacts of ``env``: rod points (K, 3) [m], total force on the rod (K, 3) [N]
    (normal + friction), unit normals (K, 3), normal force magnitudes (K,) [N]."""
    z3, z1 = np.zeros((0, 3)), np.zeros(0)
    if st is None or not hasattr(st, "contact_count"):
        return z3, z3, z3, z1
    k = int(np.asarray(st.contact_count)[env])
    if k == 0:
        return z3, z3, z3, z1
    p = np.asarray(st.contact_rod_point, dtype=np.float64)[env, :k]
    n = np.asarray(st.contact_normal, dtype=np.float64)[env, :k]
    fn = np.asarray(st.contact_normal_force, dtype=np.float64)[env, :k]
    f = n * fn[:, None]
    if hasattr(st, "contact_friction_force"):
        f = f + np.asarray(st.contact_friction_force, dtype=np.float64)[env, :k]
    return p.copy(), f, n.copy(), fn.copy()


def contact_rows(st, env: int = 0) -> dict[str, np.ndarray]:
    """What each active contact row of ``env`` (rows as :func:`contacts_from_stats`) touches: ``edge`` (K,) the rod
    edge, ``gap`` (K,) [m], ``obstacle`` (K,) (−1 on an edge-pair row) and ``partner_edge`` (K,) (−1 on an obstacle
    row)."""
    k = int(np.asarray(st.contact_count)[env]) if st is not None and hasattr(st, "contact_count") else 0
    if k == 0:
        z = np.zeros(0, np.int64)
        return {"edge": z, "gap": np.zeros(0), "obstacle": z.copy(), "partner_edge": z.copy()}
    return {"edge": np.asarray(st.contact_edge, np.int64)[env, :k].copy(),
            "gap": np.asarray(st.contact_gap, np.float64)[env, :k].copy(),
            "obstacle": np.asarray(st.contact_obstacle, np.int64)[env, :k].copy(),
            "partner_edge": np.asarray(st.contact_partner_edge, np.int64)[env, :k].copy()}


def _replace_gravity(spec, g):
    if hasattr(spec, "sim") and hasattr(spec.sim, "gravity"):
        return dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, gravity=tuple(g)))
    try:
        return dataclasses.replace(spec, gravity=tuple(g))
    except (TypeError, ValueError):
        return spec


def builtin_spec():
    """Spec of the paper arm (assets/scenes/arm.toml)."""
    return load_scene(asset_path("scenes/arm.toml"))


def load(path: str | Path):
    """``sim.load_scene`` (clear ``SceneError`` on bad files), refusing a rod the sliders cannot steer (fewer than
    ``workbench.session.teleop.MIN_NODES`` nodes) before anything of the open scene changes."""

    spec = load_scene(path)
    for rod in spec.rods:
        try:
            control_points(rod.nodes)
        except ValueError as exc:
            raise ValueError(f"{Path(path).name}: rod {rod.name!r}: {exc}") from None
    return spec
