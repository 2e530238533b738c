"""Glue between a batched task core (``policies.tasks.base.BatchedTask``) and a :class:`Recorder`.

:class:`TaskProbe` is a :class:`~policies.tasks.base.StepObserver` of the core (``core.add_observer``;
:meth:`TaskProbe.detach` removes it), so every env's frames are recorded with the full simulator state
*before* the vector env auto-resets finished envs:

* after ``core.reset(mask)``: for each reset env, end its open episode (``complete=False``), begin a
  new one if that env's quota is not used up, and log the reset frame (control_step 0);
* after ``core.step(action)``: log one frame per recorded env (control_step = episode step count)
  with reward, reward terms, tip error, energies, solver stats, contacts; end the episodes that
  finished (terminated/truncated) or reached ``max_steps``;
* with ``per_sim_step=True`` also a frame after every intermediate simulator step (scalars from the
  StepStats only; the control-step frame carries the reward).

Per env ``i`` at most ``quota[i] = episodes // B + (i < episodes % B)`` episodes are recorded (the
split ``policies.learning.evaluation`` uses). Attach it before the env's first ``reset``::

    probe = TaskProbe(recorder, episodes=4, meta={"policy": "random", "seed": 0})
    probe.attach(venv)            # SB3 adapter, BatchedVecEnv or the core itself
"""
from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np
from sim.contact import load_mesh_triangles
from sim.geometry import material_curvature, quat_to_matrix, quat_z_to, to_xyzw

from .schema import StaticScene

__all__ = ["TaskProbe", "record_hook", "core_of", "integrated_twist", "scene_from_specs",
           "task_static_scene", "task_target"]


def core_of(env: Any) -> Any:
    """The BatchedTask core of an SB3 adapter (``.venv.core``), a BatchedVecEnv (``.core``) or a core."""
    for _ in range(4):
        if hasattr(env, "sim") and hasattr(env, "state") and hasattr(env, "step_count"):
            return env
        nxt = getattr(env, "core", None) or getattr(env, "venv", None) or getattr(env, "unwrapped", None)
        if nxt is None or nxt is env:
            break
        env = nxt
    raise TypeError(f"cannot find a rodlab task core in {type(env).__name__} (need .core / .venv.core)")


def integrated_twist(theta: np.ndarray, ref_twist: np.ndarray) -> np.ndarray:
    """Integrated twist m_i = θ_i − θ_{i−1} + β_i per node (..., N) [rad]; 0 at the two end nodes.
    theta (..., N-1) edge angles, ref_twist (..., N) reference twist."""
    out = np.zeros(ref_twist.shape)
    out[..., 1:-1] = theta[..., 1:] - theta[..., :-1] + ref_twist[..., 1:-1]
    return out


def task_target(core: Any) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(target positions (B, 3) [m] or None, target quaternions (B, 4) x y z w or None) of a task core.
    2-D targets (x, z) are placed at y = 0."""
    pos = quat = None
    tgt = getattr(core, "target", None)
    if tgt is not None and hasattr(tgt, "pos"):            # FollowTargetMotion
        pos = np.asarray(tgt.pos, np.float64)
    elif isinstance(tgt, np.ndarray):
        pos = np.asarray(tgt, np.float64)
    elif getattr(core, "target_pos", None) is not None:
        pos = np.asarray(core.target_pos, np.float64)
    if getattr(core, "target_quat", None) is not None:
        quat = np.asarray(core.target_quat, np.float64)
    if pos is not None and pos.shape[-1] == 2:
        pos = np.stack([pos[..., 0], np.zeros(pos.shape[:-1]), pos[..., 1]], axis=-1)
    return pos, quat


def scene_from_specs(specs: Any, *, rod_radius: float = 0.05, planar: bool = False,
                     plane_half_size: float = 2.0) -> StaticScene:
    """StaticScene from ``sim.scene.obstacles`` specs (capsules, spheres, boxes, meshes; a plane is shown as a
    thin square box of half size ``plane_half_size`` [m] centred at its point)."""
    caps, crad, sc, sr, bc, bh, bq, meshes = [], [], [], [], [], [], [], []
    for o in specs or ():
        kind = getattr(o, "type", "")
        if kind == "capsule":
            caps.append([o.start, o.end])
            crad.append(o.radius)
        elif kind == "sphere":
            sc.append(o.center)
            sr.append(o.radius)
        elif kind == "box":
            bc.append(o.position)
            bh.append(o.half_extents)
            bq.append(to_xyzw(np.asarray(o.orientation, np.float64)))  # recordings store x y z w
        elif kind == "plane":
            n = np.asarray(o.normal, np.float64)
            n = n / np.linalg.norm(n)
            bc.append(np.asarray(o.point, np.float64) - 1e-3 * n)
            bh.append([plane_half_size, plane_half_size, 1e-3])
            bq.append(to_xyzw(quat_z_to(n)))
        elif kind == "mesh":
            tri = np.asarray(load_mesh_triangles(o.path, o.scale), np.float64).reshape(-1, 3)
            v = tri @ quat_to_matrix(o.orientation).T + np.asarray(o.position, np.float64)
            meshes.append((v, np.arange(len(v)).reshape(-1, 3)))

    def arr(a, shape):
        return np.asarray(a, np.float64).reshape(shape) if a else None

    return StaticScene(rod_radius=rod_radius, capsules=arr(caps, (-1, 2, 3)), capsule_radii=arr(crad, (-1,)),
                       sphere_centers=arr(sc, (-1, 3)), sphere_radii=arr(sr, (-1,)), box_centers=arr(bc, (-1, 3)),
                       box_half_sizes=arr(bh, (-1, 3)), box_quats=arr(bq, (-1, 4)), meshes=tuple(meshes),
                       planar=planar)


def task_static_scene(core: Any, env: int) -> StaticScene:
    """Obstacles of env ``env`` of a task core as a :class:`StaticScene`: the per-env fence of the 3-D
    obstacle task, else the model's scene obstacles, else the task's ``scene_capsules()``; with the
    model's rod radius, the planar flag and, for a scene of several rods, the rod layout."""
    model = getattr(core, "model", None) or getattr(core.sim, "model", None)
    return dataclasses.replace(_task_obstacles(core, env, model), **_rod_layout(model))


def _rod_layout(model: Any) -> dict[str, Any]:
    """``rod_node_offsets``/``rod_names`` of a model of several rods (nothing for one rod)."""
    off = getattr(model, "rod_node_offsets", None)
    if off is None or len(off) <= 2:
        return {}
    names = tuple(getattr(model, "rod_names", ()) or ())
    return {"rod_node_offsets": np.asarray(off, np.int64), "rod_names": names if len(names) == len(off) - 1 else ()}


def _task_obstacles(core: Any, env: int, model: Any) -> StaticScene:
    radius = float(getattr(model, "radius", 0.05))
    planar = bool(getattr(core, "planar", False))
    specs = getattr(getattr(model, "spec", None), "obstacles", None)
    if getattr(core, "fences", None) is not None:
        caps = np.asarray(core.fences[env], np.float64)
        r = float(core.config.fence.radius)
    elif specs:
        return scene_from_specs(specs, rod_radius=radius, planar=planar)
    elif hasattr(core, "scene_capsules"):
        c, r = core.scene_capsules()
        caps = np.asarray(c, np.float64).reshape(-1, 2, 3)
    else:
        return StaticScene(rod_radius=radius, planar=planar)
    if len(caps) == 0:
        return StaticScene(rod_radius=radius, planar=planar)
    return StaticScene(rod_radius=radius, capsules=caps, capsule_radii=np.full(len(caps), float(r)), planar=planar)


_STAT_SCALARS = (("energy/stretch", "energy_stretch"), ("energy/bend", "energy_bend"), ("energy/twist", "energy_twist"),
                 ("energy/contact", "energy_contact"), ("energy/kinetic", "energy_kinetic"),
                 ("energy/gravity", "energy_gravity"), ("solver/residual", "residual"),
                 ("solver/converged", "converged"), ("solver/failed", "failed"), ("solver/substeps", "substeps"),
                 ("solver/midpoint_fallbacks", "midpoint_fallbacks"),
                 ("solver/newton_iters", "newton_iters"), ("contact/max_penetration", "max_penetration"))


def _stats_scalars(stats: Any, e: int) -> dict[str, float]:
    """Scalars of env ``e`` from a StepStats (fields that are missing are skipped)."""
    out: dict[str, float] = {}
    for name, field in _STAT_SCALARS:
        v = getattr(stats, field, None)
        if v is not None:
            out[name] = float(np.asarray(v)[e])
    cnt = getattr(stats, "contact_count", None)
    if cnt is not None:
        c = int(cnt[e])
        out["contact/count"] = float(c)
        fn = np.asarray(stats.contact_normal_force)
        out["contact/max_normal_force"] = float(np.max(np.abs(fn[e, :c]))) if c else 0.0
        dropped = getattr(stats, "contact_dropped", None)
        if dropped is not None and np.asarray(dropped).shape[:1] == np.asarray(cnt).shape[:1]:
            out["contact/dropped"] = float(dropped[e])  # rows not listed: the listed ones are not all
        net = getattr(stats, "contact_force", None)
        if net is not None and np.asarray(net).shape[:1] == np.asarray(cnt).shape[:1]:
            out["contact/net_force"] = float(np.linalg.norm(np.asarray(net)[e]))  # every contact counted
    return out


class TaskProbe:
    """Record the episodes of a task core into ``recorder`` (see module docstring).

    episodes: total number of episodes to record (split over the B envs); meta: extra metadata for every
    episode (policy, seed, ...; task and scene are filled in); max_steps: end a recorded episode after
    this many control steps (``complete=False``; the driver then resets that env, see :meth:`cut_envs`);
    per_sim_step: also log intermediate simulator steps; ref_frames: also log reference directors d1, d2.
    """

    def __init__(self, recorder: Any, *, episodes: int, meta: Mapping[str, Any] | None = None,
                 max_steps: int | None = None, per_sim_step: bool = False, ref_frames: bool = False) -> None:
        if episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {episodes}")
        self.rec = recorder
        self.episodes = int(episodes)
        self.meta = dict(meta or {})
        self.max_steps = None if max_steps is None else int(max_steps)
        self.per_sim_step = bool(per_sim_step)
        self.ref_frames = bool(ref_frames)
        self.core: Any = None
        self._saved: list[tuple[Any, str]] = []
        self._cut: np.ndarray | None = None

    # ------------------------------------------------------------------ attach / detach
    def attach(self, env: Any) -> "TaskProbe":
        """Start recording ``env`` (SB3 adapter, BatchedVecEnv or core) before its first reset. Attaching
        again (``evaluate(..., eval_seeds=k)`` builds one env per seed) detaches from the previous env
        (its open episodes are ended with ``complete=False``) and records ``episodes`` more; the k-th env's
        ``seed`` metadata is ``meta["seed"] + k`` (evaluate's seed sequence)."""
        if self.core is not None:
            self.detach(end_open=True)
        self._attaches = getattr(self, "_attaches", -1) + 1
        task_id, obj = None, env
        for _ in range(4):                              # the vector env knows the gymnasium id
            task_id = task_id or getattr(obj, "task_id", None)
            obj = getattr(obj, "venv", None) or getattr(obj, "core", None)
            if obj is None:
                break
        core = core_of(env)
        self.core = core
        B = core.envs
        self.quota = np.array([self.episodes // B + (i < self.episodes % B) for i in range(B)], np.int64)
        self.begun = np.zeros(B, np.int64)
        self._cut = np.zeros(B, bool)
        self._last_stats = None
        self._wall = 0.0
        core.add_observer(self)
        cfg = getattr(core, "config", None)
        self.substeps = int(getattr(cfg, "substeps", 1))
        self.dt = float(getattr(getattr(core, "model", None) or core.sim.model, "dt", getattr(cfg, "dt", 0.05)))
        base = {"task": task_id or type(core).__name__.removesuffix("Core"),
                "scene": str(getattr(cfg, "scene", "") or ""), "envs": B, "dt": self.dt,
                "substeps": self.substeps, "control_dt": self.dt * self.substeps,
                "per_sim_step": self.per_sim_step}
        if not hasattr(self, "_user_meta"):
            self._user_meta = dict(self.meta)
        self.meta = {**base, **self._user_meta}
        if isinstance(self.meta.get("seed"), int) and self._attaches:
            self.meta["seed"] += self._attaches
        return self

    def detach(self, *, end_open: bool = False) -> None:
        """Stop observing the core; with ``end_open`` end this env's open episodes (``complete=False``)."""
        if self.core is not None:
            if end_open:
                for e in range(self.core.envs):
                    if self.rec.is_open(e):
                        self.rec.end_episode(env=e, complete=False)
            self.core.remove_observer(self)
            self.core = None

    @property
    def done(self) -> bool:
        """True when every env has recorded its quota and no episode is open."""
        return self.core is not None and bool(np.all(self.begun >= self.quota)) and \
            not any(self.rec.is_open(e) for e in range(self.core.envs))

    def cut_envs(self) -> np.ndarray:
        """(B,) bool: envs whose recorded episode was cut at ``max_steps`` and that should be reset now
        (their quota is not used up). Clears the flags."""
        m = self._cut & (self.begun < self.quota)
        self._cut[:] = False
        return m

    # ------------------------------------------------------------------ StepObserver
    def on_reset(self, core, mask: np.ndarray) -> None:
        for e in np.flatnonzero(mask):
            if self.rec.is_open(int(e)):
                self.rec.end_episode(env=int(e), complete=False)
            if self.begun[e] < self.quota[e]:
                self.begun[e] += 1
                meta = {**self.meta, "env_episode": int(self.begun[e] - 1)}
                if "seed" in meta and "env_seed_index" not in meta:
                    meta["env_seed_index"] = int(e)      # env e of a batch seeded `seed` (SeedSequence child e)
                self.rec.begin_episode(meta, task_static_scene(core, int(e)), env=int(e))
        rec_envs = [int(e) for e in np.flatnonzero(mask) if self.rec.is_open(int(e))]
        if rec_envs:
            self._log(rec_envs, stats=None, control=True, reward=None, info=None)

    def on_sim_step(self, core, substep: int, stats) -> None:
        self._last_stats = stats
        if self.per_sim_step and substep + 1 < self.substeps:
            envs = [e for e in range(core.envs) if self.rec.is_open(e)]
            if envs:
                self._log(envs, stats=stats, control=False, reward=None, info=None)

    def on_step(self, core, reward, terminated, truncated, info) -> None:
        self._wall = core.last_step_seconds
        envs = [e for e in range(core.envs) if self.rec.is_open(e)]
        if envs:
            self._log(envs, stats=self._last_stats, control=True, reward=reward, info=info)
        done = np.asarray(terminated, bool) | np.asarray(truncated, bool)
        for e in envs:
            if done[e]:
                self.rec.end_episode(env=e, complete=True)
            elif self.max_steps is not None and core.step_count[e] >= self.max_steps:
                self.rec.end_episode(env=e, complete=False)
                self._cut[e] = True

    # ------------------------------------------------------------------ one frame per env
    def _log(self, envs: list[int], *, stats, control: bool, reward, info) -> None:
        core = self.core
        sim, state, ctrl = core.sim, core.state, core.ctrl
        pos = np.asarray(state.node_pos)
        m1, m2, _t = sim.material_frames(state)  # every back-end has them; a failure is not recorded as "no frames"
        m1, m2 = np.asarray(m1), np.asarray(m2)
        planar = bool(getattr(core, "planar", False))
        model = getattr(core, "model", None) or sim.model
        pc = int(getattr(model, "planar_component", 0))
        kbar = np.asarray(ctrl.kappa_bar)
        kap = material_curvature(pos[envs], m1[envs], m2[envs]) if m1 is not None else None
        twist = None
        if not planar and getattr(getattr(core, "converter", None), "cfg", None) is not None and \
                getattr(core.converter.cfg, "has_twist", False) and hasattr(state, "node_ref_twist"):
            twist = integrated_twist(np.asarray(state.edge_theta)[envs], np.asarray(state.node_ref_twist)[envs])
        tpos, tquat = task_target(core)
        times = np.asarray(state.time)
        for j, e in enumerate(envs):
            kw: dict[str, Any] = {}
            if m1 is not None:
                kw.update(m1=m1[e], m2=m2[e])
            if self.ref_frames and hasattr(state, "edge_ref_d1"):
                d1 = np.asarray(state.edge_ref_d1)[e]
                kw.update(d1=d1, d2=np.cross(np.asarray(state.edge_tangent)[e], d1))
            if planar:
                kw["kappa_bar"] = kbar[e, :, :1]
                if kap is not None:
                    kw["kappa"] = kap[j, :, pc:pc + 1]
            else:
                kw["kappa_bar"] = kbar[e]
                if kap is not None:
                    kw["kappa"] = kap[j]
            if twist is not None:
                kw.update(tau_bar=np.asarray(ctrl.tau_bar)[e], tau=twist[j])
            if tpos is not None:
                kw["target_pos"] = tpos[e]
                if tquat is not None:
                    kw["target_quat"] = tquat[e]
            sc: dict[str, float] = {}
            if tpos is not None:
                sc["tip_error"] = float(np.linalg.norm(pos[e, -1] - tpos[e]))
            if stats is not None:
                sc.update(_stats_scalars(stats, e))
                if getattr(stats, "contact_count", None) is not None and \
                        np.asarray(stats.contact_rod_point).ndim == 3 and stats.contact_rod_point.shape[1] > 0:
                    c = int(stats.contact_count[e])
                    kw.update(contact_points=stats.contact_rod_point[e, :c], contact_normals=stats.contact_normal[e, :c],
                              contact_normal_force=stats.contact_normal_force[e, :c],
                              contact_friction=stats.contact_friction_force[e, :c],
                              contact_edge=stats.contact_edge[e, :c], contact_obstacle=stats.contact_obstacle[e, :c],
                              contact_partner_edge=stats.contact_partner_edge[e, :c])
            if reward is not None:
                sc["reward"] = float(reward[e])
                sc["solver/wall_time"] = self._wall
                for k, v in (info or {}).items():
                    if k.startswith("reward/") and not k.startswith("_"):
                        sc["reward_terms/" + k[7:]] = float(np.asarray(v)[e])
                if info is not None and "orientation_distance" in info:
                    sc["ori_error"] = float(np.asarray(info["orientation_distance"])[e])
                if info is not None and "newton_iters" in info:      # summed over the control step
                    sc["solver/newton_iters_control"] = float(np.asarray(info["newton_iters"])[e])
            cs = int(core.step_count[e]) if control else int(core.step_count[e]) + 1
            kw["scalars"] = {k: v for k, v in sc.items() if np.isfinite(v)}
            sim_step = None
            if self.per_sim_step:
                sim_step = int(round(float(times[e]) / self.dt))
            self.rec.log_step(env=e, control_step=cs, sim_time=float(times[e]), sim_step=sim_step,
                              node_pos=pos[e], **kw)


@contextlib.contextmanager
def record_hook(path: Any, *, episodes: int, meta: Mapping[str, Any] | None = None,
                **probe_kw: Any) -> Iterator[Callable[[Any], TaskProbe]]:
    """Context manager giving an ``env_hook`` for ``policies.learning.evaluation.evaluate`` that records every
    evaluated episode to ``path`` (written atomically when the block ends without an exception)::

        with record_hook("recordings/eval.rrd", episodes=n, meta={"policy": p, "seed": s}) as hook:
            result = evaluate(p, task, episodes=n, seed=s, env_hook=hook)
    """
    from .recorder import Recorder

    with Recorder(path) as rec:
        probe = TaskProbe(rec, episodes=episodes, meta=meta, **probe_kw)
        try:
            yield probe.attach
            probe.detach(end_open=True)
        finally:
            probe.detach()
