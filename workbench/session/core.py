"""The workbench core: session state machine, independent of any GUI (testable headless).

Modes: ``teleop`` (sliders drive the rod), ``policy`` (a policy drives a task episode; the
user can take over by hand and hand back), ``replay`` (a recorded episode is shown; the live
session is paused meanwhile). Every live sim step stores a :class:`Snapshot`, so the session can
be rewound to any earlier frame and continued from there.

Thread safety: every public method takes ``self.lock``; the sim thread (``workbench.session.runner``)
and GUI callbacks call them concurrently.
"""
from __future__ import annotations

import dataclasses
import threading
from pathlib import Path
from typing import Callable, Literal

import numpy as np

from policies.control import smoothing_basis
from sim.analysis import reach
from workbench.session import obstacles as obst
from workbench.session.frame import Frame
from workbench.session.history import History, Snapshot
from workbench.session.pull import Pull, control_force, grab, held_point, point
from workbench.session.recorder import SessionRecorder
from workbench.session.simbridge import ActionRefused, LiveSim, builtin_spec, load
from workbench.session.teleop import KAPPA_LIMIT, TWIST_LIMIT, Teleop

Mode = Literal["teleop", "policy", "replay"]


class Workbench:
    """Headless workbench session around one live rod.

    Args:
        spec: a ``SceneSpec`` (``sim.load_scene``).
        scene_path: where the scene came from (default for "save").
        history: how many snapshots to keep for rewinding.
        substeps: sim steps per teleop control step (delta mode).
    """

    def __init__(self, spec, *, scene_path: str | Path | None = None, history: int = 6000,
                 substeps: int = 2):
        self.lock = threading.RLock()
        self.scene_path = Path(scene_path) if scene_path else None
        self.live = LiveSim(spec)
        self.teleop_rod = 0  # the rod the teleop sliders steer (index into teleop_rods())
        self._teleops: dict[int, Teleop] = {}  # the other rods' teleop state, kept for switching back
        self.teleop = _teleop_for(self.live, 0, substeps)
        self.mode: Mode = "teleop"
        self.playing = True
        self.history = History(history)
        self.frame_index = 0
        self.policy = None  # workbench.session.policy_session.PolicySession while a policy is loaded
        self.hand_control = False  # user took over from the policy
        self.replay = None  # workbench.session.replay.ReplaySession while a recording is open
        self.recorder = None  # workbench.session.recorder.SessionRecorder while recording
        self.obstacles: list[obst.ObstacleEdit] = obst.edits_from_spec(spec)
        self.on_scene_changed: list[Callable[[], None]] = []
        self._last_scalars: dict = {}
        self._reach_warm = None  # the last inverse-statics answer of reach_to (its warm start)
        self.reach_angle = float("nan")  # the tip frame's angle from reach_to's target orientation [rad] (nan: none)
        self.pull: Pull | None = None  # a hand on the live rod (workbench.session.pull), None when nothing is held
        self._push_snapshot()

    @classmethod
    def from_path(cls, path: str | Path, **kw) -> "Workbench":
        return cls(load(path), scene_path=path, **kw)

    @classmethod
    def builtin(cls, **kw) -> "Workbench":
        """The paper arm (assets/scenes/arm.toml) without obstacles."""
        return cls(builtin_spec(), **kw)

    # ------------------------------------------------------------------ stepping
    def step(self) -> None:
        """Advance the live session by one sim step, or an open recording by one frame (whatever the play
        state)."""
        with self.lock:
            if self.mode == "replay":
                if self.replay is not None:
                    self.replay.step_frame()
                return
            scalars: dict = {}
            self._apply_hand()
            if self.policy is not None and self.mode == "policy":
                hand = self.teleop if self.hand_control else None
                scalars = self.policy.sim_step(self.live, hand=hand)
                self._sync_policy_obstacles()
            else:
                self.teleop.apply(self.live.ctrl, self.live.rest_ctrl)
                self.live.step()
            self.frame_index += 1
            hand = {"pull_force": float(np.linalg.norm(self.pull.force)) if self.pull is not None else 0.0,
                    "hand": float(self.hand_control)}
            self._last_scalars = {**self.live.step_scalars(), **scalars, **hand}
            self._push_snapshot()
            if self.recorder is not None:
                self.recorder.log(self.frame())

    # ------------------------------------------------------------------ the hand
    def grab(self, at) -> int:
        """Grab the live rod at the node nearest the point ``at`` (3,) [m] (its neighbours held too,
        workbench.session.pull); from the next step a spring pulls them toward the hand (:meth:`move_hand`), in teleop and
        under a running policy alike (the policy sees the disturbance). Returns the grabbed node. ActionRefused in
        replay; ValueError for a point that is not 3 finite numbers."""
        with self.lock:
            if self.mode == "replay":
                raise ActionRefused("a recording cannot be pulled: close it to pull the live rod")
            self.pull = grab(self.live.state.node_pos[0], at, self.live.rod_offsets)
            return self.pull.node

    def move_hand(self, to) -> None:
        """Move the hand of the grab in progress to ``to`` (3,) [m] (nothing held: ignored)."""
        p = point(to, "hand position")
        with self.lock:
            if self.pull is not None:
                self.pull.pointer = p

    def release(self) -> None:
        """Let go of the rod (from the next step no force)."""
        with self.lock:
            self.pull = None

    def _apply_hand(self) -> None:
        """Set the stepped control's node forces to the hand's springs (None when nothing is held)."""
        ctrl, pull = self.live.ctrl, self.pull
        if pull is None:
            ctrl.force = None
            return
        m = self.live.model
        ctrl.force = control_force(pull, self.live.state, 0, m.node_mass, float(m.dt))

    def advance(self) -> bool:
        """Step if playing; returns whether anything moved."""
        with self.lock:
            if self.mode == "replay":
                return self.replay is not None and self.replay.advance()
            if not self.playing:
                return False
            self.step()
            return True

    def set_playing(self, playing: bool) -> None:
        with self.lock:
            if self.mode == "replay" and self.replay is not None:
                self.replay.playing = playing
            else:
                self.playing = bool(playing)

    def reset(self) -> None:
        """Fresh rod (and a fresh episode in policy mode); clears the rewind history."""
        with self.lock:
            self.live.reset()
            self.teleop.reset()
            for tel in self._teleops.values():  # the other rods are back at rest too
                tel.reset()
            if self.policy is not None:
                self.policy.reset(self.live)
                self._sync_policy_obstacles()
            self.frame_index = 0
            self._last_scalars = {}
            self.history.clear()
            self._push_snapshot()

    def set_gravity(self, on: bool) -> None:
        """Gravity on/off (teleop only: a task keeps its own settings)."""
        with self.lock:
            if self.policy is not None:
                raise ActionRefused("gravity belongs to the task while a policy is loaded")
            self.live.set_gravity(on)

    # ------------------------------------------------------------------ frames
    def frame(self) -> Frame:
        """What to draw now (the replayed frame in replay mode)."""
        with self.lock:
            if self.mode == "replay" and self.replay is not None:
                return self.replay.frame()
            targets = self.policy.targets() if self.policy is not None else None
            fr = self.live.frame(targets=targets, scalars=self._last_scalars)
            if self.policy is not None:
                fr.target_wxyz = self.policy.target_wxyz()
            if self.pull is not None:
                fr.hand = np.stack([held_point(self.pull, fr.node_pos), self.pull.pointer])
                fr.hand_force = self.pull.force.copy()
            return fr

    @property
    def tip(self) -> np.ndarray:
        with self.lock:
            return self.live.tip

    @property
    def tip_frame(self) -> np.ndarray | None:
        """(3, 3) the live rod's tip edge frame, columns (m1, m2, t); None in 2-D."""
        with self.lock:
            return self.live.tip_frame()

    # ------------------------------------------------------------------ snapshots / rewind
    def _push_snapshot(self) -> None:
        self.history.append(Snapshot(
            index=self.frame_index, time=float(np.asarray(self.live.state.time)[0]),
            sim=self.live.snapshot(), teleop=self.teleop.snapshot(),
            driver=self.policy.snapshot() if self.policy is not None else None,
            mode=self.mode, scalars=dict(self._last_scalars)))

    def rewind(self, index: int) -> None:
        """Go back to frame ``index`` of this session; later frames are dropped, play pauses."""
        with self.lock:
            snap = self.history.get(int(index))
            self.live.restore(snap.sim)
            self.teleop.restore(snap.teleop)
            if self.policy is not None and snap.driver is not None:
                self.policy.restore(snap.driver)
                self._sync_policy_obstacles()
            self.frame_index = snap.index
            self._last_scalars = dict(snap.scalars)
            self.history.truncate_after(snap.index)
            self.playing = False

    # ------------------------------------------------------------------ modes
    def set_teleop_mode(self, mode) -> None:
        with self.lock:
            self.teleop.set_mode(mode)

    def set_teleop_value(self, k: int, comp: int, value: float) -> None:
        with self.lock:
            self.teleop.set_value(k, comp, value)

    def reach_to(self, target, *, node: int = -1, orientation=None) -> float:
        """Teleop by inverse statics (docs/physics.md §3.10): set the steered rod's absolute natural curvature at the
        control points to what holds its node ``node`` (default the tip; a control point dragged in the page) on
        ``target`` (3,) [m] at equilibrium, obstacles and contact left out
        (the rod may press against an obstacle on its way); the twist sliders go to 0. With ``orientation`` (3, 3),
        the tip edge's target frame (columns m1, m2, t; 3-D), the natural twist at the control points is solved for
        too and set on the twist sliders. A few Gauss–Newton iterations per call, warm-started from the last call,
        so repeated calls (a dragged target) converge as they go. Returns the distance [m] between the target and
        the equilibrium node of the curvature set (the frame's angle from its target [rad]: ``reach_angle``).
        Raises ActionRefused in policy mode or with several rods, ValueError for a target that is not 3 finite
        numbers or an orientation that is not a rotation (or in 2-D, or not at the tip)."""
        tgt = np.asarray(target, dtype=np.float64).reshape(-1)
        if tgt.shape != (3,) or not np.all(np.isfinite(tgt)):
            raise ValueError(f"reach target must be 3 finite numbers [m], got {target!r}")
        frames = None
        if orientation is not None:
            frames = np.asarray(orientation, dtype=np.float64)
            if (frames.shape != (3, 3) or not np.all(np.isfinite(frames))
                    or not np.allclose(frames.T @ frames, np.eye(3), atol=1e-6) or np.linalg.det(frames) < 0.0):
                raise ValueError(f"reach orientation must be a rotation (3 x 3, columns m1, m2, t), got {orientation!r}")
            if node != -1:
                raise ValueError("reach orientation is the tip edge's: node must be the tip (-1)")
            frames = frames[None]
        with self.lock:
            if self.mode != "teleop":
                raise ActionRefused("reach steers the rod by hand: stop the policy (or take over) first")
            if len(self.teleop_rods()) > 1:
                raise ActionRefused("reach steers a scene of one rod")
            spec = self.live.current_spec()
            if frames is not None and spec.sim.mode != "3d":
                raise ValueError("reach orientation: a 2-D scene has no tip frame to turn")
            contact = spec.contact
            if hasattr(contact, "enabled"):
                contact = dataclasses.replace(contact, enabled=False)
            spec = dataclasses.replace(spec, obstacles=(), contact=contact)
            basis = smoothing_basis(self.teleop.converter.cfg)
            # a warm start holds for one scene only, and for targets with a frame or without
            key = (id(self.live.base_spec), self.live.gravity, frames is None)
            warm = self._reach_warm[1] if self._reach_warm is not None and self._reach_warm[0] == key else None
            tel = self.teleop
        res = reach(spec, tgt[None], basis=basis, tip=node, bound=KAPPA_LIMIT, max_iterations=4,  # outside the lock
                    warm=warm, orientations=frames, twist_bound=TWIST_LIMIT)
        with self.lock:
            self._reach_warm = (key, res)
            if tel is self.teleop and self.mode == "teleop":
                if tel.mode != "absolute":
                    tel.set_mode("absolute")
                tel.values[:, :2] = res.coefficients[0]
                tel.values[:, 2] = 0.0 if frames is None else res.twist_coefficients[0]
            self.reach_angle = float("nan") if frames is None else float(res.orientation_error[0])
        return float(res.error[0])

    def teleop_rods(self) -> list[str]:
        """Names of the rods teleop can steer (the live scene's rods)."""
        with self.lock:
            names = list(getattr(self.live.model, "rod_names", ()) or ())
            off = self.live.rod_offsets
            n = 1 if off is None else len(off) - 1
            return names if len(names) == n else [f"rod {i}" for i in range(n)]

    def set_teleop_rod(self, index: int) -> None:
        """Steer rod ``index`` of the live scene; the rod left keeps its last control and its slider values
        come back when it is chosen again. Raises ValueError for an index the scene does not have."""
        with self.lock:
            n = len(self.teleop_rods())
            if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= int(index) < n:
                raise ValueError(f"teleop rod must be an index in [0, {n}), got {index!r}")
            index = int(index)
            if index == self.teleop_rod:
                return
            self._teleops[self.teleop_rod] = self.teleop
            tel = self._teleops.pop(index, None) or _teleop_for(self.live, index, self.teleop.substeps)
            tel.set_mode(self.teleop.mode)
            self.teleop, self.teleop_rod = tel, index

    def start_policy(self, session) -> None:
        """Hand the rod to a ``PolicySession``: the page shows its task's simulator and episode."""
        with self.lock:
            if self.policy is None:
                self._teleop_live = self.live
            self.policy = session
            self.live = LiveSim.adopt(session.core)
            self.obstacles = obst.edits_from_spec(self.live.base_spec) if self.live.base_spec else []
            self._policy_obstacles_version = -1
            self._sync_policy_obstacles(notify=False)
            self.mode = "policy"
            self.pull = None  # the hand lets go when the rod it held changes
            self.hand_control = False
            self.frame_index = 0
            self._last_scalars = {}
            self.history.clear()
            self._push_snapshot()
            self.playing = True
        for cb in list(self.on_scene_changed):
            cb()

    def _sync_policy_obstacles(self, *, notify: bool = True) -> None:
        """Follow obstacles that the task re-places (new episode / rewind)."""
        p = self.policy
        if p is None or p.obstacles_version == getattr(self, "_policy_obstacles_version", None):
            return
        self._policy_obstacles_version = p.obstacles_version
        edits = p.display_obstacles()
        if edits is None:
            return
        self.obstacles = edits
        if notify:
            for cb in list(self.on_scene_changed):
                cb()

    def stop_policy(self) -> None:
        """Back to teleop on the scene that was open before the policy."""
        with self.lock:
            if self.policy is None:
                return
            self.policy = None
            self.hand_control = False
            self.mode = "teleop"
            self.pull = None  # the hand lets go when the rod it held changes
            self.live = getattr(self, "_teleop_live", self.live)
            self.obstacles = obst.edits_from_spec(self.live.base_spec)
            self.frame_index = 0
            self._last_scalars = {}
            self.history.clear()
            self._push_snapshot()
        for cb in list(self.on_scene_changed):
            cb()

    def take_over(self) -> None:
        """The user drives (teleop sliders, absolute values = what the policy reached)."""
        with self.lock:
            if self.policy is None:
                return
            self.hand_control = True
            K, T = self.policy.accumulated()
            self.teleop.mode = "absolute"
            self.teleop.values[:, :2] = K
            self.teleop.values[:, 2] = T

    def hand_back(self) -> None:
        """The policy drives again, continuing from the hand-set natural curvature."""
        with self.lock:
            if self.policy is None:
                return
            acc = self.teleop.accumulated()
            self.policy.set_accumulated(acc[:, :2], acc[:, 2])
            self.hand_control = False

    def open_replay(self, session) -> None:
        with self.lock:
            self.replay = session
            self.mode = "replay"
            self.pull = None  # the hand lets go when the rod it held changes

    def close_replay(self) -> None:
        with self.lock:
            self.replay = None
            self.mode = "policy" if self.policy is not None else "teleop"

    # ------------------------------------------------------------------ obstacles / scene
    def _replace_spec(self, spec, *, keep_state: bool = True) -> None:
        if self.recorder is not None:
            self.recorder.new_episode()
        self.live.set_spec(spec, keep_state=keep_state)
        if self.pull is not None and self.pull.nodes.max() >= self.live.n_nodes:  # the held nodes are gone
            self.pull = None
        first, n = _rod_span(self.live, self.teleop_rod)
        if n is None:  # the scene lost the steered rod: back to the first one
            self.teleop_rod, self._teleops = 0, {}
            self.teleop = _teleop_for(self.live, 0, self.teleop.substeps)
        elif (first, n) != (self.teleop.first_node, self.teleop.n_nodes):  # another layout of rods
            self._teleops = {}
            self.teleop = _teleop_for(self.live, self.teleop_rod, self.teleop.substeps)
        self.obstacles = obst.edits_from_spec(spec)
        for cb in list(self.on_scene_changed):
            cb()

    def add_obstacle(self, edit: "obst.ObstacleEdit") -> int:
        """Add an obstacle (rebuilds the model, keeps the rod state); returns its index."""
        with self.lock:
            self._replace_spec(obst.spec_with(self.live.base_spec, self.obstacles + [edit]))
            return len(self.obstacles) - 1

    def delete_obstacle(self, index: int) -> None:
        with self.lock:
            edits = [e for i, e in enumerate(self.obstacles) if i != index]
            self._replace_spec(obst.spec_with(self.live.base_spec, edits))

    def resize_obstacle(self, index: int, size) -> None:
        """New size of obstacle ``index`` (rebuilds the model, keeps the rod state). ``size`` (3,) [m]: sphere radius;
        capsule/cylinder radius, length; box half sizes; mesh scale [-] (first value)."""
        import dataclasses

        with self.lock:
            v = np.asarray(size, dtype=np.float64).reshape(3)
            e = dataclasses.replace(self.obstacles[index])
            if e.kind == "sphere":
                e.radius = float(v[0])
            elif e.kind in ("capsule", "cylinder"):
                e.radius, e.length = float(v[0]), float(v[1])
            elif e.kind == "box":
                e.half_extents = v.copy()
            elif e.kind == "mesh":
                e.scale, e.mesh_scale3 = float(v[0]), None
            edits = [e if i == index else o for i, o in enumerate(self.obstacles)]
            self._replace_spec(obst.spec_with(self.live.base_spec, edits))

    def set_obstacle_pose(self, index: int, position, wxyz) -> None:
        """Move/rotate obstacle ``index``; contact follows at the next step (no rebuild)."""
        with self.lock:
            if not 0 <= index < len(self.obstacles):  # removed by another action since the page sent the pose
                raise ActionRefused(f"obstacle {index + 1} is gone (the scene has {len(self.obstacles)})")
            e = self.obstacles[index]
            e.position = np.asarray(position, dtype=np.float64).reshape(3).copy()
            e.wxyz = np.asarray(wxyz, dtype=np.float64).reshape(4).copy()
            obst.apply_pose(self.live, index, e)
            if self.recorder is not None:
                self.recorder.new_episode()

    def save_scene(self, path: str | Path) -> Path:
        """Write the current scene (with edited obstacles) to TOML (``sim.scene.spec`` dump, atomic); that file is
        the open scene from now on. The page confines ``path`` to its scenes folder (``workbench.session.files``)."""
        with self.lock:
            spec = obst.spec_with(self.live.base_spec, self.obstacles)
            out = obst.write_scene(spec, Path(path))
            self.scene_path = out
            return out

    def load_scene(self, path: str | Path) -> None:
        """Load a scene file; the rod is reset."""
        with self.lock:
            spec = load(path)
            self.scene_path = Path(path)
            self._replace_spec(spec, keep_state=False)
            self.reset()

    # ------------------------------------------------------------------ recording
    def start_recording(self, path: str | Path) -> Path:
        """Record every following live frame to ``path`` (.rrd) until :meth:`stop_recording`."""
        with self.lock:
            if self.recorder is not None:
                raise RuntimeError(f"already recording to {self.recorder.path}")
            meta = {"policy": self.policy.name if self.policy is not None else "teleop",
                    "task": self.policy.task if self.policy is not None else "",
                    "scene": str(self.scene_path or ""), "source": "workbench"}
            self.recorder = SessionRecorder(path, meta=meta, obstacles=lambda: self.obstacles,
                                            rod_radius=self.live.rod_radius,
                                            planar=getattr(self.live.model, "mode", "3d") == "2d",
                                            rod_names=lambda: getattr(self.live.model, "rod_names", ()))
            return self.recorder.path

    def stop_recording(self) -> Path | None:
        """Write the recording file; returns its path (None if no frame was recorded)."""
        with self.lock:
            rec, self.recorder = self.recorder, None
        return rec.close() if rec is not None else None


def _rod_span(live, index: int) -> tuple[int, int | None]:
    """(first node, node count) of rod ``index`` of the live scene; (0, None) when it has no such rod."""
    off = live.rod_offsets
    if off is None:
        return (0, int(live.n_nodes)) if index == 0 else (0, None)
    if not 0 <= index < len(off) - 1:
        return 0, None
    return int(off[index]), int(off[index + 1] - off[index])


def _teleop_for(live, index: int, substeps: int) -> Teleop:
    first, n = _rod_span(live, index)
    return Teleop(n_nodes=n, substeps=substeps, first_node=first)
