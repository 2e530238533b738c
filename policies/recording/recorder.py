"""Episode recorder: buffers numpy frames per episode and writes them to a rerun .rrd file.

Usage (one env)::

    with Recorder("recordings/run.rrd") as rec:
        rec.begin_episode({"task": "rodlab/FollowTarget-v0", "seed": 0, "policy": "random"},
                          StaticScene(rod_radius=0.05))
        for k in range(S):
            rec.log_step(control_step=k, sim_time=k * 0.1, node_pos=pos,               # (N, 3) [m]
                         scalars={"reward": r, "tip_error": d})
        rec.end_episode()
    # file exists only now (atomic os.replace); an exception discards everything

Batched envs: pass ``env=e`` to every call; each env has at most one open episode. Every episode
is its own rerun recording (see :mod:`policies.recording.schema`). While recording, each episode is
streamed to a part file in a hidden folder beside the output (``.NAME.rrd.parts-<pid>/``); at
``close()`` the parts are merged (``rerun rrd merge``) into a temp file in the same folder, which is
``os.replace``-d onto the final name. A killed process never leaves a file under the final name.

Per frame, ``log_step`` only copies the arrays (float32); the rerun calls happen once per episode
(``send_columns`` per entity) in ``end_episode``.
"""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import time
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
import rerun as rr
import rerun_bindings
from sim.geometry import quat_z_to, to_xyzw

from . import schema as S
from .events import LEVELS as EVENT_LEVELS
from .events import from_columns as find_events
from .schema import RecordingError, StaticScene

__all__ = ["Recorder", "rerun_cli"]

_ROD_COLOR = (230, 120, 30)
_FRAME_COLORS = {"m1": (40, 170, 40), "m2": (150, 60, 200), "d1": (120, 200, 120), "d2": (190, 150, 220)}
_CONTACT_COLORS = {"normal": (120, 120, 120), "normal_force": (220, 30, 30), "friction_force": (30, 90, 230)}
_OBSTACLE_COLOR = (150, 150, 150, 200)
_TARGET_COLOR = (30, 120, 255)
_CURV_COLORS = {"commanded": (30, 120, 255), "actual": (230, 120, 30)}


def rerun_cli() -> str:
    """Path of the ``rerun`` command-line binary shipped in the rerun-sdk wheel."""
    env = os.environ.get("RERUN_CLI_PATH")
    if env:
        return env
    try:
        import rerun_cli as _rc
        cand = Path(_rc.__file__).with_name("rerun")
        if cand.exists():
            return str(cand)
    except ImportError:
        pass
    cand = Path(sys.executable).with_name("rerun")
    if cand.exists():
        return str(cand)
    found = shutil.which("rerun")
    if found:
        return found
    raise RecordingError("cannot find the 'rerun' binary (install rerun-sdk, or set RERUN_CLI_PATH)")


def _vec(a: Any, name: str, shape: tuple[int | None, ...], dtype=np.float32) -> np.ndarray:
    """Copy ``a`` as ``dtype`` and check its shape (None = any length) and finiteness."""
    try:
        arr = np.array(a, dtype=dtype, copy=True)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"log_step: {name}: not a numeric array ({exc})") from None
    sh = arr.shape
    if len(sh) != len(shape) or (sh != shape and any(s is not None and s != n for s, n in zip(shape, sh))):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise RecordingError(f"log_step: {name}: expected shape {want}, got {arr.shape}")
    if dtype is not np.int64 and not np.isfinite(arr.sum()) and not np.isfinite(arr).all():
        raise RecordingError(f"log_step: {name}: contains NaN or inf")
    return arr


def _quat_z_to(d: np.ndarray) -> np.ndarray:
    """Unit quaternions (K, 4) x y z w (rerun's order) rotating +z onto the unit vectors d (K, 3)."""
    return to_xyzw(quat_z_to(d))


def _vertex_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(ln > 0, ln, 1.0)


_BLUEPRINTS: dict[tuple, bytes] = {}  # (application id, planar, plotted paths) -> the blueprint as .rrd bytes
_MAX_BLUEPRINTS = 64


def _release(ep: "_Episode") -> None:
    """Close ``ep``'s stream and free it. rerun keeps the native side of a dropped stream (its two threads and
    buffers) until orphaned streams are cleaned up, which only ``rr.init`` does; a recorder opens one stream
    per episode, so a long workbench session would otherwise keep every episode's threads."""
    rec, ep.rec = ep.rec, None
    if rec is None:
        return
    try:
        rec.disconnect()
    finally:
        del rec
        rerun_bindings.flush_and_cleanup_orphaned_recordings()


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class _ContactRows(NamedTuple):
    """One frame's contact rows as ``log_step`` validated them (C rows; the optional ones None when not given)."""
    points: np.ndarray
    normals: np.ndarray
    normal_force: np.ndarray
    friction: np.ndarray | None
    edge: np.ndarray | None
    obstacle: np.ndarray | None
    partner_edge: np.ndarray | None


class _Episode:
    """Buffers of one open episode (one rerun recording streamed to one part file)."""

    def __init__(self, rec: rr.RecordingStream, part: Path, env: int, index: int, meta: dict[str, Any],
                 scene: StaticScene) -> None:
        self.rec, self.part, self.env, self.index, self.meta, self.scene = rec, part, env, index, meta, scene
        self.n_nodes: int | None = None
        self.keys: set[tuple[int, int, int]] = set()
        self.control_step: list[int] = []
        self.sim_ns: list[int] = []
        self.sim_step: list[int] | None = None
        self.pos: list[np.ndarray] = []
        # quantity -> (frame indices, arrays)
        self.rows: dict[str, tuple[list[int], list[Any]]] = {}
        self.scalar_rows: list[tuple[int, dict[str, float]]] = []
        self.target_has_quat: bool | None = None
        self.reward_sum = 0.0
        self.has_reward = False
        self.max_fn = 0.0

    def add(self, name: str, frame: int, value: Any) -> None:
        idx, vals = self.rows.setdefault(name, ([], []))
        idx.append(frame)
        vals.append(value)


class Recorder:
    """Record rod episodes to ``path`` (a ``.rrd`` file, written atomically at :meth:`close`).

    Keyword options: ``force_scale`` [m/N] arrow length per newton of contact force;
    ``frame_scale`` [m] arrow length of unit directors/normals; ``on_error`` what leaving a
    ``with`` block by an exception does: ``"discard"`` (default, no file) or ``"keep"`` (write the
    finished episodes); ``application_id`` of the rerun recordings; ``blueprint``: store a default
    viewer layout (3-D view, reward/tip error/energy/solver plots, curvature) with the first episode.
    """

    def __init__(self, path: str | os.PathLike[str], *, force_scale: float = S.DEFAULT_FORCE_SCALE,
                 frame_scale: float = S.DEFAULT_FRAME_SCALE, on_error: Literal["discard", "keep"] = "discard",
                 application_id: str = S.APPLICATION_ID, blueprint: bool = True) -> None:
        self.path = Path(path)
        if self.path.suffix != ".rrd":
            raise RecordingError(f"{self.path}: recording files must end in .rrd")
        if self.path.exists() and self.path.is_dir():
            raise RecordingError(f"{self.path}: is a directory")
        if not (force_scale > 0 and frame_scale > 0):
            raise RecordingError("force_scale and frame_scale must be > 0")
        if on_error not in ("discard", "keep"):
            raise RecordingError(f"on_error must be 'discard' or 'keep', got {on_error!r}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.force_scale, self.frame_scale, self.on_error = float(force_scale), float(frame_scale), on_error
        self.application_id = application_id
        self.blueprint = bool(blueprint)
        self.run_id = uuid.uuid4().hex[:12]
        self._parts_dir = self.path.parent / f".{self.path.name}.parts-{os.getpid()}-{self.run_id}"
        self._remove_stale()
        self._open: dict[int, _Episode] = {}
        self._parts: list[Path] = []
        self._next_index = 0
        self._closed = False
        self.summaries: list[dict[str, Any]] = []
        self._ok_names: set[str] = set()

    def _remove_stale(self) -> None:
        """Delete part folders (of any recording in this folder) and temp files for this output left by
        processes that no longer exist (a killed recording)."""
        prefixes = (f".{self.path.name}.parts-", f".{self.path.stem}.")
        cands = set(self.path.parent.glob(f".{self.path.stem}.*")) | set(self.path.parent.glob(".*.rrd.parts-*"))
        for x in sorted(cands):
            name = x.name
            rest = next((name[len(p):] for p in prefixes if name.startswith(p)), None)
            if rest is None and ".rrd.parts-" in name and x.is_dir():
                rest = name.rsplit(".rrd.parts-", 1)[1]
            if rest is None or (x.is_file() and not name.endswith(".tmp.rrd")):
                continue
            try:
                pid = int(rest.split("-")[0])
            except ValueError:
                continue
            if pid == os.getpid() or _pid_alive(pid):
                continue
            if x.is_dir():
                shutil.rmtree(x, ignore_errors=True)
            else:
                x.unlink(missing_ok=True)

    # ------------------------------------------------------------------ context manager
    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None or self.on_error == "keep":
            self.close()
        else:
            self.abort()

    def _check_open(self) -> None:
        if self._closed:
            raise RecordingError(f"{self.path}: recorder is closed")

    @property
    def episodes_written(self) -> int:
        return len(self.summaries)

    def is_open(self, env: int = 0) -> bool:
        """True if ``env`` has an episode in progress."""
        return env in self._open

    # ------------------------------------------------------------------ episodes
    def begin_episode(self, meta: Mapping[str, Any], scene: StaticScene | None = None, *, env: int = 0) -> int:
        """Start an episode for ``env``; returns its index in the file. ``meta``: task, seed, policy,
        scene (TOML text or path), ... (str/int/float/bool values). ``scene``: static geometry (and the rod
        layout of a scene of several rods, stored as the ``rods`` property)."""
        self._check_open()
        if env in self._open:
            raise RecordingError(f"begin_episode: env {env} already has an open episode (call end_episode)")
        scene = (scene or StaticScene()).validated()
        index = self._next_index
        self._next_index += 1
        full = {"task": "", "seed": -1, "policy": "", "scene": ""}
        full.update(S.sanitize_meta(dict(meta)))
        full.update(S.provenance())
        full.update(env=int(env), episode=index, schema_version=S.SCHEMA_VERSION, force_scale=self.force_scale,
                    frame_scale=self.frame_scale, rod_radius=scene.rod_radius, planar=scene.planar,
                    run_id=self.run_id, created_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
        self._parts_dir.mkdir(exist_ok=True)
        part = self._parts_dir / f"ep{index:05d}.rrd"
        rec = rr.RecordingStream(self.application_id, recording_id=f"{self.run_id}/env{env}/ep{index}",
                                 make_default=False, make_thread_default=False)
        rec.save(str(part))
        rec.set_log_time_enabled(False)
        rec.send_recording_name(f"{full['task'] or 'episode'} ep{index} env{env}")
        rec.send_property(S.META_PROPERTY, rr.AnyValues(**full))
        if scene.rod_node_offsets is not None:
            rods: dict[str, Any] = {"node_offsets": scene.rod_node_offsets}
            if scene.rod_names:
                rods["names"] = list(scene.rod_names)
            rec.send_property(S.RODS_PROPERTY, rr.AnyValues(**rods))
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._log_scene(rec, scene)
        self._open[env] = _Episode(rec, part, env, index, full, scene)
        return index

    def _log_scene(self, rec: rr.RecordingStream, sc: StaticScene) -> None:
        o = S.OBSTACLES
        if sc.capsules is not None and len(sc.capsules):
            a, b = sc.capsules[:, 0], sc.capsules[:, 1]
            d = b - a
            ln = np.linalg.norm(d, axis=1)
            u = d / np.where(ln > 0, ln, 1.0)[:, None]
            u[ln == 0] = (0.0, 0.0, 1.0)
            rec.log(f"{o}/capsules", rr.Capsules3D(lengths=ln, radii=sc.capsule_radii, translations=a,
                                                   quaternions=_quat_z_to(u), colors=_OBSTACLE_COLOR),
                    rr.AnyValues(axis_points=sc.capsules.ravel()), static=True)
        if sc.sphere_centers is not None and len(sc.sphere_centers):
            r = sc.sphere_radii
            rec.log(f"{o}/spheres", rr.Ellipsoids3D(centers=sc.sphere_centers, half_sizes=np.repeat(r[:, None], 3, 1),
                                                    colors=_OBSTACLE_COLOR, fill_mode="solid"),
                    rr.AnyValues(sphere_radii=r), static=True)
        if sc.box_centers is not None and len(sc.box_centers):
            q = sc.box_quats if sc.box_quats is not None else np.tile([0.0, 0, 0, 1], (len(sc.box_centers), 1))
            rec.log(f"{o}/boxes", rr.Boxes3D(centers=sc.box_centers, half_sizes=sc.box_half_sizes, quaternions=q,
                                             colors=_OBSTACLE_COLOR, fill_mode="solid"),
                    rr.AnyValues(box_quats=q.ravel(), has_box_quats=sc.box_quats is not None), static=True)
        for i, (v, f) in enumerate(sc.meshes):
            rec.log(f"{o}/mesh_{i}", rr.Mesh3D(vertex_positions=v, triangle_indices=f,
                                               vertex_normals=_vertex_normals(v, f), albedo_factor=_OBSTACLE_COLOR),
                    static=True)

    def _episode(self, env: int, what: str) -> _Episode:
        self._check_open()
        ep = self._open.get(env)
        if ep is None:
            raise RecordingError(f"{what}: env {env} has no open episode (call begin_episode first)")
        return ep

    def log_step(self, *, env: int = 0, control_step: int, sim_time: float, node_pos: Any,
                 sim_step: int | None = None, m1: Any = None, m2: Any = None, d1: Any = None, d2: Any = None,
                 contact_points: Any = None, contact_normals: Any = None, contact_normal_force: Any = None,
                 contact_friction: Any = None, contact_edge: Any = None, contact_obstacle: Any = None,
                 contact_partner_edge: Any = None,
                 kappa_bar: Any = None, kappa: Any = None, tau_bar: Any = None, tau: Any = None,
                 target_pos: Any = None, target_quat: Any = None,
                 scalars: Mapping[str, float] | None = None) -> None:
        """Buffer one frame of ``env``'s open episode.

        node_pos (N, 3) [m] (N fixed per episode); m1, m2, d1, d2 (N-1, 3) unit directors per edge;
        contacts (C rows, C may be 0): contact_points (C, 3) [m] on the rod, contact_normals (C, 3) unit
        (obstacle -> rod), contact_normal_force (C,) [N], optional contact_friction (C, 3) [N],
        contact_edge / contact_obstacle / contact_partner_edge (C,) int (a row of an edge pair: obstacle -1 and the
        other edge; of an obstacle: partner -1); kappa_bar / kappa (N,) or (N, k<=2) integrated
        curvature (commanded natural / actual), tau_bar / tau (N,) integrated twist [rad];
        target_pos (3,) [m], target_quat (4,) x y z w; scalars: name -> float (see schema.STANDARD_SCALARS).
        control_step and sim_time [s] must not decrease; a frame key (control_step, sim_time, sim_step)
        may be logged once.
        """
        ep = self._episode(env, "log_step")
        pos = _vec(node_pos, "node_pos", (ep.n_nodes, 3))
        if ep.n_nodes is None:
            if pos.shape[0] < 2:
                raise RecordingError(f"log_step: node_pos: need at least 2 nodes, got {pos.shape[0]}")
            off = ep.scene.rod_node_offsets
            if off is not None and int(off[-1]) != pos.shape[0]:
                raise RecordingError(f"log_step: node_pos: {pos.shape[0]} nodes, but the scene's rod_node_offsets "
                                     f"{off.tolist()} end at {int(off[-1])}")
            ep.n_nodes = pos.shape[0]
            ep.sim_step = [] if sim_step is not None else None
        n = ep.n_nodes
        cs = int(control_step)
        t = float(sim_time)
        if not np.isfinite(t):
            raise RecordingError(f"log_step: sim_time must be finite, got {sim_time!r}")
        ns = int(round(t * 1e9))
        if (sim_step is None) != (ep.sim_step is None):
            raise RecordingError("log_step: sim_step: give it on every frame of an episode or on none")
        if ep.control_step and (cs < ep.control_step[-1] or ns < ep.sim_ns[-1]):
            raise RecordingError(f"log_step: control_step/sim_time went backwards (env {env}: "
                                 f"{ep.control_step[-1]}, {ep.sim_ns[-1] * 1e-9:g} s -> {cs}, {t:g} s)")
        key = (cs, ns, -1 if sim_step is None else int(sim_step))
        if key in ep.keys:
            raise RecordingError(f"log_step: env {env}: frame control_step={cs}, sim_time={t:g} already logged")
        f = len(ep.pos)
        # validate everything before mutating the buffers
        frames = {k: _vec(v, k, (n - 1, 3)) for k, v in (("m1", m1), ("m2", m2), ("d1", d1), ("d2", d2))
                  if v is not None}
        contact = None
        if contact_points is not None or contact_normals is not None or contact_normal_force is not None:
            if contact_points is None or contact_normals is None or contact_normal_force is None:
                raise RecordingError("log_step: contacts need contact_points, contact_normals and "
                                     "contact_normal_force together")
            cp = _vec(contact_points, "contact_points", (None, 3))
            c = cp.shape[0]
            ids = {name: None if v is None else _vec(v, "contact_" + name, (c,), np.int64)
                   for name, v in (("edge", contact_edge), ("obstacle", contact_obstacle),
                                   ("partner_edge", contact_partner_edge))}
            contact = _ContactRows(
                cp, _vec(contact_normals, "contact_normals", (c, 3)),
                _vec(contact_normal_force, "contact_normal_force", (c,), np.float64),
                None if contact_friction is None else _vec(contact_friction, "contact_friction", (c, 3)), **ids)
        curv = {}
        for name, v in (("kappa_bar", kappa_bar), ("kappa", kappa)):
            if v is not None:
                a = np.asarray(v)
                a = _vec(a.reshape(n, 1) if a.ndim == 1 and a.shape[0] == n else a, name, (n, None))
                if a.shape[1] not in (1, 2):
                    raise RecordingError(f"log_step: {name}: expected (N,) or (N, 1|2), got {a.shape}")
                curv[name] = a
        for name, v in (("tau_bar", tau_bar), ("tau", tau)):
            if v is not None:
                curv[name] = _vec(v, name, (n,))
        tgt = None
        if target_pos is not None:
            tp = _vec(target_pos, "target_pos", (3,))
            tq = None if target_quat is None else _vec(target_quat, "target_quat", (4,))
            if ep.target_has_quat is not None and ep.target_has_quat != (tq is not None):
                raise RecordingError("log_step: target_quat: give it with every target_pos of an episode or never")
            tgt = (tp, tq)
        elif target_quat is not None:
            raise RecordingError("log_step: target_quat needs target_pos")
        sc = {}
        ok = self._ok_names
        for k, v in (scalars or {}).items():
            if k not in ok:
                ok.add(S.check_scalar_name(k))
            try:
                sc[k] = float(v)
            except (TypeError, ValueError):
                raise RecordingError(f"log_step: scalar {k!r}: not a number ({v!r})") from None
        # commit
        ep.keys.add(key)
        ep.control_step.append(cs)
        ep.sim_ns.append(ns)
        if ep.sim_step is not None:
            ep.sim_step.append(int(sim_step))
        ep.pos.append(pos)
        for k, a in frames.items():
            ep.add(k, f, a)
        if contact is not None:
            ep.add("contacts", f, contact)
            if contact.normal_force.size:
                ep.max_fn = max(ep.max_fn, float(np.abs(contact.normal_force).max()))
        for k, a in curv.items():
            ep.add(k, f, a)
        if tgt is not None:
            ep.target_has_quat = tgt[1] is not None
            ep.add("target", f, tgt)
        if sc:
            ep.scalar_rows.append((f, sc))
            r = sc.get("reward")
            if r is not None and math.isfinite(r):
                ep.reward_sum += r
                ep.has_reward = True

    def end_episode(self, *, env: int = 0, complete: bool = True) -> dict[str, Any]:
        """Send the buffered columns of ``env``'s episode and finish its part file.
        Returns a summary dict (episode, env, steps, return, max_contact_force)."""
        ep = self._episode(env, "end_episode")
        del self._open[env]
        try:
            self._send(ep)
            summary = {"episode": ep.index, "env": env, "steps": len(ep.pos),
                       "return": ep.reward_sum if ep.has_reward else float("nan"),
                       "max_contact_force": ep.max_fn, "complete": bool(complete)}
            ep.rec.send_property("summary", rr.AnyValues(**summary))
        finally:
            _release(ep)
        self._parts.append(ep.part)
        self.summaries.append(summary)
        return summary

    def _send(self, ep: _Episode) -> None:
        rec = ep.rec
        if not ep.pos:
            return
        if self.blueprint and ep.index == 0:
            paths = {f"{S.SCALARS}/{k}" for _, sc in ep.scalar_rows for k in sc}
            for name, comps in (("kappa_bar", "kappa"), ("kappa", "kappa"), ("tau_bar", "twist"), ("tau", "twist")):
                if name in ep.rows:
                    k = ep.rows[name][1][0]
                    paths |= ({f"{S.CURVATURE}/twist"} if comps == "twist" else
                              {f"{S.CURVATURE}/kappa{j + 1}" for j in range(k.shape[1])})
            self._send_blueprint(ep, paths)
        cs_all = np.asarray(ep.control_step, np.int64)
        ns_all = np.asarray(ep.sim_ns, np.int64)
        ss_all = None if ep.sim_step is None else np.asarray(ep.sim_step, np.int64)

        def idx(frames: Any = None) -> list[rr.TimeColumn]:
            sel = slice(None) if frames is None else np.asarray(frames, np.int64)
            cols = [rr.TimeColumn("control_step", sequence=cs_all[sel]),
                    rr.TimeColumn("sim_time", duration=ns_all[sel].astype("timedelta64[ns]"))]
            if ss_all is not None:
                cols.append(rr.TimeColumn("sim_step", sequence=ss_all[sel]))
            return cols

        n = ep.n_nodes
        P = np.stack(ep.pos)                                     # (S, N, 3)
        off = ep.scene.rod_node_offsets
        rec.log(S.ROD, rr.LineStrips3D.from_fields(radii=[ep.scene.rod_radius], colors=[_ROD_COLOR]), static=True)
        if off is None or len(off) <= 2:
            rec.send_columns(S.ROD, indexes=idx(), columns=rr.LineStrips3D.columns(strips=P))
        else:  # one strip per rod in each frame: the viewer draws no line across a joint edge
            strips = [P[f, int(a):int(b)] for f in range(P.shape[0]) for a, b in zip(off[:-1], off[1:])]
            rec.send_columns(S.ROD, indexes=idx(), columns=rr.LineStrips3D.columns(strips=strips).partition(
                [len(off) - 1] * P.shape[0]))
        joints = [] if off is None else [int(b) - 1 for b in off[1:-1]]  # edges between two rods: no frame
        mid = 0.5 * (P[:, 1:] + P[:, :-1])                       # (S, N-1, 3)
        for name in S.FRAME_ENTITIES:
            if name not in ep.rows:
                continue
            fr, vals = ep.rows[name]
            V = np.stack(vals) * self.frame_scale
            if joints:
                V[:, joints] = 0.0  # zero-length arrows keep one arrow per edge (the reader's layout)
            path = f"{S.ROD}/{name}"
            rec.log(path, rr.Arrows3D.from_fields(colors=[_FRAME_COLORS[name]]), static=True)
            rec.send_columns(path, indexes=idx(fr), columns=rr.Arrows3D.columns(
                origins=mid[fr].reshape(-1, 3), vectors=V.reshape(-1, 3)).partition([n - 1] * len(fr)))
        if "contacts" in ep.rows:
            self._send_contacts(rec, idx, *ep.rows["contacts"])
        xs = np.linspace(0.0, 1.0, n, dtype=np.float32)
        for name, kind in (("kappa_bar", "commanded"), ("kappa", "actual")):
            if name in ep.rows:
                fr, vals = ep.rows[name]
                A = np.stack(vals)                               # (S', N, k)
                for j in range(A.shape[2]):
                    self._send_curve(rec, idx(fr), f"{S.CURVATURE}/kappa{j + 1}/{kind}", xs, A[:, :, j], kind)
        for name, kind in (("tau_bar", "commanded"), ("tau", "actual")):
            if name in ep.rows:
                fr, vals = ep.rows[name]
                self._send_curve(rec, idx(fr), f"{S.CURVATURE}/twist/{kind}", xs, np.stack(vals), kind)
        if "target" in ep.rows:
            fr, vals = ep.rows["target"]
            tp = np.stack([v[0] for v in vals])
            kw: dict[str, Any] = {"translation": tp}
            if ep.target_has_quat:
                kw["quaternion"] = np.stack([v[1] for v in vals])
                rec.log(S.TARGET, rr.TransformAxes3D(axis_length=2 * self.frame_scale), static=True)
            rec.log(f"{S.TARGET}/marker", rr.Points3D([[0.0, 0.0, 0.0]], radii=0.02, colors=[_TARGET_COLOR]),
                    static=True)
            rec.send_columns(S.TARGET, indexes=idx(fr), columns=rr.Transform3D.columns(**kw))
        cols: dict[str, tuple[list[int], list[float]]] = {}
        for f, sc in ep.scalar_rows:
            for k, v in sc.items():
                c = cols.get(k)
                if c is None:
                    c = cols[k] = ([], [])
                c[0].append(f)
                c[1].append(v)
        for key, (fr, vals) in cols.items():
            rec.send_columns(f"{S.SCALARS}/{key}", indexes=idx(fr),
                             columns=rr.Scalars.columns(scalars=np.asarray(vals, np.float64)))
        self._send_events(rec, idx, ep, cols)

    @staticmethod
    def _send_events(rec, idx, ep: _Episode, cols: dict[str, tuple[list[int], list[float]]]) -> None:
        """The episode's events (``policies.recording.events``) as text at ``events``, found from the scalars just sent."""
        nf = len(ep.pos)
        dense = {}
        for key, (fr, vals) in cols.items():
            a = np.full(nf, np.nan)
            a[np.asarray(fr, np.int64)] = vals
            dense[key] = a
        cc = None
        if "contact/count" not in dense and "contacts" in ep.rows:
            fr, rows = ep.rows["contacts"]
            cc = np.zeros(nf)
            cc[np.asarray(fr, np.int64)] = [len(c.points) for c in rows]
        found = find_events(nf, dense, cc)
        if found:
            rec.send_columns(S.EVENTS, indexes=idx([e.frame for e in found]), columns=rr.TextLog.columns(
                text=[e.text for e in found], level=[EVENT_LEVELS.get(e.kind, "INFO") for e in found]))

    def _send_blueprint(self, ep: _Episode, paths: set[str]) -> None:
        """Default viewer layout (with the first episode of the file only), as the file's first part."""
        import rerun.blueprint as rrb

        def has(prefix: str) -> bool:
            return any(p == prefix or p.startswith(prefix + "/") for p in paths)

        plots = [rrb.TimeSeriesView(origin=S.SCALARS, contents=[f"{S.SCALARS}/reward", f"{S.SCALARS}/reward_terms/**"],
                                    name="reward")]
        if has(f"{S.SCALARS}/tip_error") or has(f"{S.SCALARS}/ori_error"):
            plots.append(rrb.TimeSeriesView(origin=S.SCALARS, contents=[f"{S.SCALARS}/tip_error",
                                                                         f"{S.SCALARS}/ori_error"], name="tip error"))
        tabs = [rrb.TimeSeriesView(origin=f"{S.SCALARS}/{g}", name=g) for g in ("energy", "solver", "contact")
                if has(f"{S.SCALARS}/{g}")]
        curv = [rrb.Spatial2DView(origin=f"{S.CURVATURE}/{k}", name=f"{k} (blue commanded, orange actual)")
                for k in S.CURVATURE_KINDS if has(f"{S.CURVATURE}/{k}")]
        right = plots + ([rrb.Tabs(*tabs)] if tabs else []) + ([rrb.Tabs(*curv)] if curv else [])
        # camera framing the 1 m arm and the task workspace; planar tasks are seen along +y (x-z plane)
        if ep.scene.planar:
            eye = rrb.EyeControls3D(position=(0.3, -2.8, 0.45), look_target=(0.3, 0.0, 0.45), eye_up=(0, 0, 1))
        else:
            eye = rrb.EyeControls3D(position=(2.0, -2.4, 1.6), look_target=(0.1, 0.0, 0.45), eye_up=(0, 0, 1))
        view = rrb.Spatial3DView(origin="world", name="rod", eye_controls=eye)
        bp = rrb.Blueprint(rrb.Horizontal(view, rrb.Vertical(*right),
                                          column_shares=[3, 2]), collapse_panels=False)
        key = (self.application_id, bool(ep.scene.planar), tuple(sorted(paths)))
        data = _BLUEPRINTS.get(key)
        if data is None:
            # rerun makes a blueprint in a stream of its own that it never frees (two threads each): it is made
            # once per layout in a process, and its bytes go into each file as a part of their own
            from rerun.blueprint.api import create_in_memory_blueprint

            data = create_in_memory_blueprint(application_id=self.application_id, blueprint=bp).storage.drain_as_bytes()
            if len(_BLUEPRINTS) < _MAX_BLUEPRINTS:
                _BLUEPRINTS[key] = data
        part = self._parts_dir / "blueprint.rrd"
        part.write_bytes(data)
        self._parts.insert(0, part)

    def _send_curve(self, rec, indexes, path: str, xs: np.ndarray, Y: np.ndarray, kind: str) -> None:
        s, n = Y.shape
        # 2-D views draw +y downwards: store y = CURVE_Y_SIGN * value so that positive curvature points up
        pts = np.stack([np.broadcast_to(xs, (s, n)), S.CURVE_Y_SIGN * Y.astype(np.float32)], axis=-1)   # (S', N, 2)
        rec.log(path, rr.LineStrips2D.from_fields(colors=[_CURV_COLORS[kind]]), static=True)
        rec.send_columns(path, indexes=indexes, columns=rr.LineStrips2D.columns(strips=pts))

    def _send_contacts(self, rec, idx, fr: list[int], vals: list[_ContactRows]) -> None:
        counts = np.array([v.points.shape[0] for v in vals], np.int64)
        pts = np.concatenate([v.points for v in vals]).reshape(-1, 3)
        nrm = np.concatenate([v.normals for v in vals]).reshape(-1, 3)
        fn = np.concatenate([v.normal_force for v in vals]).reshape(-1)
        extra: dict[str, np.ndarray] = {"normal_force": fn.astype(np.float64)}
        for name in ("edge", "obstacle", "partner_edge"):
            if any(getattr(v, name) is not None for v in vals):
                extra[name] = np.concatenate([getattr(v, name) if getattr(v, name) is not None
                                              else np.full(v.points.shape[0], -1, np.int64) for v in vals])
        base = S.CONTACTS
        rec.log(base, rr.Points3D.from_fields(radii=[0.012], colors=[(220, 30, 30)]), static=True)
        cols = list(rr.Points3D.columns(positions=pts).partition(counts))
        if counts.sum():
            cols += list(rr.AnyValues.columns(**extra).partition(counts))
        rec.send_columns(base, indexes=idx(fr), columns=cols)
        arrows = {"normal": nrm * self.frame_scale, "normal_force": nrm * fn[:, None] * self.force_scale}
        if any(v.friction is not None for v in vals):
            fr_ = np.concatenate([v.friction if v.friction is not None else np.zeros((v.points.shape[0], 3), np.float32)
                                  for v in vals])
            arrows["friction_force"] = fr_ * self.force_scale
        for name, vec in arrows.items():
            path = f"{base}/{name}"
            rec.log(path, rr.Arrows3D.from_fields(colors=[_CONTACT_COLORS[name]]), static=True)
            rec.send_columns(path, indexes=idx(fr), columns=rr.Arrows3D.columns(
                origins=pts, vectors=vec.reshape(-1, 3)).partition(counts))

    # ------------------------------------------------------------------ finish
    def close(self, *, drop_open: bool = False) -> Path | None:
        """End open episodes (``complete=False``; dropped with ``drop_open=True``), merge the parts and
        move the result onto ``path``. Returns the path, or None if no episode was recorded."""
        if self._closed:
            return self.path if self.path.exists() else None
        for env in list(self._open):
            if drop_open:
                ep = self._open.pop(env)
                _release(ep)
                ep.part.unlink(missing_ok=True)
            else:
                self.end_episode(env=env, complete=False)
        self._closed = True
        try:
            if not self._parts:
                return None
            tmp = self.path.parent / f".{self.path.stem}.{os.getpid()}-{self.run_id}.tmp.rrd"
            if len(self._parts) == 1:
                os.replace(self._parts[0], tmp)
            else:
                r = subprocess.run([rerun_cli(), "rrd", "merge", *map(str, self._parts), "-o", str(tmp)],
                                   capture_output=True, text=True)
                if r.returncode != 0 or not tmp.exists():
                    tmp.unlink(missing_ok=True)
                    raise RecordingError(f"{self.path}: merging {len(self._parts)} episodes failed: "
                                         f"{r.stderr.strip()[-2000:]}")
            os.replace(tmp, self.path)
            return self.path
        finally:
            shutil.rmtree(self._parts_dir, ignore_errors=True)

    def abort(self) -> None:
        """Discard everything (no file is written under ``path``)."""
        for ep in self._open.values():
            try:
                _release(ep)
            except Exception:
                pass
        self._open.clear()
        self._closed = True
        shutil.rmtree(self._parts_dir, ignore_errors=True)

    def __del__(self) -> None:  # best effort: never leave part folders behind
        if not getattr(self, "_closed", True):
            try:
                self.abort()
            except Exception:
                pass
