"""Batched task core shared by the four tasks: B envs stepped by ONE ``sim.Simulator(envs=B)``.

A :class:`BatchedTask` owns the simulator, its State/Control, an :class:`ActionConverter`, one
``numpy.random.Generator`` per env and the per-env step counters. Everything per step is vectorised
numpy over the B envs; only resets loop over the envs being reset (to draw from each env's own
generator). The gymnasium single env (B = 1) and the batched VectorEnv are thin wrappers over it.

Episode protocol (docs/tasks.md §3), written once here: reset -> counter 0; each control step is
``begin_step`` (convert the action), ``substeps`` x ``sim_step`` (increment injected before each sim step) and
``end_step`` (the task's post-step hook, observation, reward, termination, info); ``step`` is exactly those
calls, and the workbench makes the same calls one sim step at a time. ``truncated`` when the counter (before
increment) equals
``timeout_steps`` (so an episode has ``timeout_steps + 1`` steps). ``terminated`` with reward -10
when the simulator failed during the step (``StepStats.failed``; reason ``"sim_failed"``) or the
reward is NaN or < -10 (reason ``"reward_explosion"``). Observations are sanitised (no NaN/inf).

Seeding: env i's generator is ``Generator(PCG64(SeedSequence(seed).spawn(B)[i]))`` for a batch
seed, which equals ``SeedSequence(seed, spawn_key=(i,))``; a single env reset with
``reset(seed=seed, options={"env_index": i})`` uses the same child and reproduces env i exactly.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, Protocol

import numpy as np

from policies.control import (
    STATE_NODES,
    ActionConverter,
    ControlConfig,
    ControlIncrement,
    Smoothing,
    control_config,
)

from .rewards import FAILURE_REWARD, reach_reward

__all__ = ["TaskConfig", "BatchedTask", "StepObserver", "RewardTermsObserver", "child_generator", "spawn_generators",
           "check_field_value"]

# Ranges of the integer settings every task shares (a huge substeps count would run for ever).
FIELD_LIMITS = {"substeps": (1, 1000), "newton_max_iter": (1, 10_000), "timeout_steps": (0, 10 ** 9)}


def check_field_value(owner: str, key: str, like: Any, value: Any) -> None:
    """Raise ValueError naming ``owner.key`` unless ``value`` has the kind of ``like`` (the field's default or
    current value): float -> a finite real number (not str/bool), int -> an integer, bool -> a bool, str -> a
    str (``scene`` may also be None). Other kinds (arrays, nested settings) are left to the task."""
    got = f"{type(value).__name__} {value!r}"
    if isinstance(like, bool):
        ok, want = isinstance(value, (bool, np.bool_)), "true/false"
    elif isinstance(like, int):
        ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
        want = "an integer"
    elif isinstance(like, float):
        ok = (isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
              and bool(np.isfinite(value)))
        want = "a finite number"
    elif isinstance(like, str) or (like is None and key == "scene"):
        ok, want = isinstance(value, str) or (value is None and key == "scene"), "a string"
    else:
        return
    if not ok:
        raise ValueError(f"{owner}.{key}: expected {want}, got {got}")
    lo, hi = FIELD_LIMITS.get(key, (None, None))
    if lo is not None and not lo <= value <= hi:
        raise ValueError(f"{owner}.{key}: must be within [{lo}, {hi}], got {value!r}")

OBS_LIMIT = 1e6  # observations are clipped to +-OBS_LIMIT and NaN -> 0 (sanitising, O5)


@dataclass(frozen=True)
class TaskConfig:
    """Settings common to every task (task configs subclass this and change the defaults).

    dt: sim time step [s]; substeps: sim steps per control step; newton_max_iter: Newton iterations
    per sim step (accepted unconverged); mode: "3d" or "2d" simulator mode; timeout_steps: episode
    truncation counter (episode = timeout_steps + 1 control steps); smoothing: spatial mapping of the
    action converter ("intended" default, "reference" = the paper's shifted mapping, "none");
    scene: scene file path relative to the repo root (the task's sim settings above override the
    file's [sim] values; a missing file is a SceneError).
    Every field is checked on construction (:func:`check_field_value`): a float field takes a finite real
    number, an int field an integer (2.5 is refused, never truncated), a bool field a bool, a str field a str.
    """

    dt: float = 0.05
    substeps: int = 2
    newton_max_iter: int = 2
    newton_tol: float = 1e-3
    mode: Literal["3d", "2d"] = "3d"
    timeout_steps: int = 500
    smoothing: Smoothing = "intended"
    scene: str | None = "assets/scenes/arm.toml"

    def __post_init__(self) -> None:
        name = type(self).__name__
        for f in dataclasses.fields(self):
            if f.default is not dataclasses.MISSING:
                check_field_value(name, f.name, f.default, getattr(self, f.name))
        if self.mode not in ("3d", "2d"):
            raise ValueError(f"{name}.mode must be '3d' or '2d', got {self.mode!r}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"{name}.dt must be > 0, got {self.dt}")
        for k in ("substeps", "newton_max_iter"):
            if int(getattr(self, k)) < 1:
                raise ValueError(f"{name}.{k} must be >= 1, got {getattr(self, k)}")
        if int(self.timeout_steps) < 0:
            raise ValueError(f"{name}.timeout_steps must be >= 0, got {self.timeout_steps}")
        if self.smoothing not in ("intended", "reference", "none"):
            raise ValueError(f"{name}.smoothing must be 'intended', 'reference' or 'none', got {self.smoothing!r}")


def child_generator(seed: int, index: int = 0) -> np.random.Generator:
    """Generator of env ``index`` for batch seed ``seed``: PCG64(SeedSequence(seed, spawn_key=(index,)))."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed), spawn_key=(int(index),))))


def spawn_generators(seed: int | None, count: int) -> list[np.random.Generator]:
    """``count`` generators from ``SeedSequence(seed).spawn(count)`` (fresh OS entropy if seed is None)."""
    return [np.random.Generator(np.random.PCG64(s)) for s in np.random.SeedSequence(seed).spawn(count)]


class StepObserver(Protocol):
    """Something that watches a task core (e.g. the recording probe): registered with
    :meth:`BatchedTask.add_observer`, called after the core's own work, never changing it."""

    def on_reset(self, core: "BatchedTask", mask: np.ndarray) -> None:
        """After ``core.reset``: ``mask`` (B,) bool are the envs just reset."""

    def on_sim_step(self, core: "BatchedTask", substep: int, stats: Any) -> None:
        """After sim step ``substep`` (0 .. substeps-1) of a control step, with its ``StepStats``."""

    def on_step(self, core: "BatchedTask", reward: np.ndarray, terminated: np.ndarray, truncated: np.ndarray,
                info: dict[str, Any]) -> None:
        """After the control step (``core.end_step``; ``core.last_step_seconds`` holds its wall time)."""


class RewardTermsObserver:
    """A :class:`StepObserver` that keeps the reward terms of the latest control step: ``latest`` maps each
    ``reward/<term>`` of that step's info to its (B,) array (the info's own arrays; empty before the first step).
    A reset leaves it alone (the vector env resets finished envs right after their last step)."""

    def __init__(self) -> None:
        self.latest: dict[str, np.ndarray] = {}

    def on_reset(self, core: "BatchedTask", mask: np.ndarray) -> None:
        pass

    def on_sim_step(self, core: "BatchedTask", substep: int, stats: Any) -> None:
        pass

    def on_step(self, core: "BatchedTask", reward: np.ndarray, terminated: np.ndarray, truncated: np.ndarray,
                info: dict[str, Any]) -> None:
        self.latest = {k: v for k, v in info.items() if k.startswith("reward/")}


@dataclass
class _ControlStep:
    """The control step in progress: its increment (None: no action), start time, sim steps taken and the
    per-env failure and solver counts summed over them."""

    increment: ControlIncrement | None
    t0: float
    failed: np.ndarray
    iters: np.ndarray
    unconv: np.ndarray
    retries: np.ndarray
    taken: int = 0


class BatchedTask:
    """Base class of the batched task cores. Subclasses set ``obs_fields``/``control`` and the hooks.

    Attributes: ``envs`` B; ``sim``, ``state``, ``ctrl``; ``converter``; ``rngs`` (B generators);
    ``step_count`` (B,) int; ``obs_dim``; ``action_dim``; ``observers`` (:class:`StepObserver`, see
    :meth:`add_observer`); ``last_step_seconds`` (wall time of the last control step, ``begin_step`` to
    ``end_step``). A control step is :meth:`step`, or the same work in parts: :meth:`begin_step`,
    ``substeps`` x :meth:`sim_step`, :meth:`end_step`.
    Hooks: ``_reset_task(idx)``, ``_post_step()``, ``_fields() -> dict name -> (B, n)``,
    ``_reward(fields) -> (reward (B,), terms dict, extra info dict)``.
    """

    #: (name, size) in the network's (alphabetical) concatenation order
    obs_fields: ClassVar[tuple[tuple[str, int], ...]] = ()
    control_kind: ClassVar[str] = "bend"

    def __init__(self, config: TaskConfig, *, envs: int = 1, seed: int | None = None):
        from .scenes import make_simulator  # lazy: needs sim

        if int(envs) < 1:
            raise ValueError(f"{type(self).__name__}: envs must be >= 1, got {envs}")
        self.config = config
        self.envs = B = int(envs)
        self.sim, self.model = make_simulator(config, envs=B, task=self)
        self.state = self.sim.reset()
        self.ctrl = self.sim.make_control()
        self.planar = config.mode == "2d"
        self.converter = ActionConverter(self._control_config(), envs=B)
        self.action_dim = self.converter.cfg.action_dim
        self.obs_dim = int(sum(n for _, n in self.obs_fields))
        self.rngs = spawn_generators(seed, B)
        self.step_count = np.zeros(B, dtype=np.int64)
        st = STATE_NODES
        step = st[1] - st[0]
        arith = all(b - a == step for a, b in zip(st, st[1:]))
        self._nodes = slice(st[0], st[-1] + 1, step) if arith else np.asarray(st)   # basic slice -> views
        self._all = np.ones(B, dtype=bool)
        self.observers: list[StepObserver] = []
        self.last_step_seconds = 0.0
        self._control: _ControlStep | None = None   # the control step in progress (begin_step .. end_step)

    # ---------------------------------------------------------------- config
    def _control_config(self) -> ControlConfig:

        return control_config(self.control_kind, substeps=self.config.substeps,  # type: ignore[arg-type]
                              smoothing=self.config.smoothing)

    # ---------------------------------------------------------------- seeding
    def seed(self, seed: int | Sequence[int] | None) -> None:
        """Re-seed every env: int -> SeedSequence(seed).spawn(B); list of B ints -> child 0 of each."""
        if seed is None or isinstance(seed, (int, np.integer)):
            self.rngs = spawn_generators(None if seed is None else int(seed), self.envs)
        else:
            seeds = list(seed)
            if len(seeds) != self.envs or not all(isinstance(s, (int, np.integer)) for s in seeds):
                raise ValueError(f"seed must be an int, None or a list of {self.envs} ints, got {seed!r}")
            self.rngs = [child_generator(int(s), 0) for s in seeds]

    # ---------------------------------------------------------------- observers
    def add_observer(self, observer: StepObserver) -> None:
        """Call ``observer`` after every reset, sim step and control step (see :class:`StepObserver`)."""
        if observer not in self.observers:
            self.observers.append(observer)

    def remove_observer(self, observer: StepObserver) -> None:
        if observer in self.observers:
            self.observers.remove(observer)

    # ---------------------------------------------------------------- episode
    def reset(self, mask: np.ndarray | None = None) -> np.ndarray:
        """Reset the envs in ``mask`` ((B,) bool, all if None); returns observations (B, obs_dim) of ALL envs.

        A reset of every env drops a control step in progress (no ``end_step``, no ``on_step``); a reset of
        some envs during one is a RuntimeError."""
        m = self._all if mask is None else np.asarray(mask, dtype=bool)
        if m.shape != (self.envs,):
            raise ValueError(f"reset mask has shape {m.shape}, expected ({self.envs},)")
        if self._control is not None:
            if not m.all():
                raise RuntimeError("reset of some envs during a control step (begin_step without end_step); "
                                   "end the step first or reset every env")
            self._control = None        # a reset of every env drops the unfinished control step
        idx = np.nonzero(m)[0]
        if idx.size:
            self.sim.reset_envs(self.state, self.ctrl, m)
            self.converter.reset(m)
            self.step_count[m] = 0
            self._reset_task(idx)           # after the sim reset, so re-placed obstacles are not undone
        obs = self.observe()
        for o in self.observers:
            o.on_reset(self, m)
        return obs

    def step(self, action) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One control step of all B envs. action (B, action_dim) in [-1, 1].

        Exactly :meth:`begin_step`, ``substeps`` x :meth:`sim_step`, :meth:`end_step` (an error on the way drops
        the unfinished step). Returns obs (B, obs_dim) float32, reward (B,) float64, terminated (B,), truncated
        (B,) bool, info dict of (B,) arrays.
        """
        if action is None:
            raise ValueError("step needs an action (B, action_dim); begin_step(None) runs a step without one")
        self.begin_step(action)
        try:
            for _ in range(self.config.substeps):
                self.sim_step()
            return self.end_step()
        finally:
            self._control = None

    @property
    def step_in_progress(self) -> bool:
        """Whether a control step has begun (:meth:`begin_step`) and not ended (:meth:`end_step`)."""
        return self._control is not None

    @property
    def sim_steps_taken(self) -> int:
        """Sim steps taken in the control step in progress (0 when none is in progress)."""
        return 0 if self._control is None else self._control.taken

    def begin_step(self, action) -> None:
        """Begin a control step of all B envs: convert ``action`` (B, action_dim) in [-1, 1] into the increment
        that the next ``substeps`` sim steps add to the controls (the converter accumulates it at once).

        ``action=None``: a control step without an action (the converter's K/T and the controls are left to
        the caller, as the workbench's hand control does). RuntimeError when a control step is in progress;
        ValueError (nothing begun) for an action of the wrong shape or with NaN/inf.
        """
        if self._control is not None:
            raise RuntimeError(f"begin_step during a control step ({self._control.taken} of "
                               f"{self.config.substeps} sim steps taken; end_step first)")
        t0 = time.perf_counter()
        inc = None if action is None else self.converter.convert(action)
        B = self.envs
        self._control = _ControlStep(increment=inc, t0=t0, failed=np.zeros(B, dtype=bool),
                                     iters=np.zeros(B, dtype=np.int64), unconv=np.zeros(B, dtype=np.int64),
                                     retries=np.zeros(B, dtype=np.int64))

    def sim_step(self, *, increment: bool = True):
        """One sim step of the control step in progress; returns its ``StepStats``.

        Adds the step's share of the increment to the controls (the k-th, k = sim steps taken so far; not when
        ``increment`` is False: the caller set the controls for this sim step), steps the simulator, calls the
        observers' ``on_sim_step`` and adds the step's failures and solver counts to those ``end_step`` reports.
        RuntimeError without a control step in progress or when its ``substeps`` sim steps are taken.
        """
        c = self._control
        if c is None:
            raise RuntimeError("sim_step without a control step in progress (begin_step first)")
        k = c.taken
        if k >= self.config.substeps:
            raise RuntimeError(f"sim_step after all {self.config.substeps} sim steps of the control step "
                               "(end_step next)")
        if increment and c.increment is not None:
            self.converter.apply(self.ctrl, c.increment, k)
        stats = self.sim.step(self.state, self.ctrl)
        for o in self.observers:
            o.on_sim_step(self, k, stats)
        c.failed |= np.asarray(stats.failed, dtype=bool)
        c.iters += np.asarray(stats.newton_iters)
        c.unconv += ~np.asarray(stats.converged, dtype=bool)
        c.retries += np.asarray(stats.substeps) > 1
        c.taken = k + 1
        return stats

    def end_step(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """End the control step in progress after its ``substeps`` sim steps: the task's post-step hook, the
        observation, the reward and its terms, truncation, termination (sim failure or reward explosion: reward
        -10), the step counter, the info; then the observers' ``on_step``. Returns what :meth:`step` returns.
        RuntimeError without a control step in progress or before all its sim steps are taken.
        """
        c = self._control
        if c is None:
            raise RuntimeError("end_step without a control step in progress (begin_step first)")
        if c.taken != self.config.substeps:
            raise RuntimeError(f"end_step after {c.taken} of {self.config.substeps} sim steps (sim_step first)")
        self._control = None
        B = self.envs
        failed = c.failed | np.asarray(self.state.failed, dtype=bool)
        self._post_step()
        fields = self._fields()
        obs = self._concat(fields)
        reward, terms, extra = self._reward(fields)
        truncated = self.step_count == self.config.timeout_steps
        self.step_count += 1
        explosion = ~failed & ~(reward >= FAILURE_REWARD)          # NaN or < -10
        terminated = failed | explosion
        reward = np.where(terminated, FAILURE_REWARD, reward)
        truncated = truncated & ~terminated
        reason = np.full(B, "", dtype=object)
        reason[explosion] = "reward_explosion"
        reason[failed] = "sim_failed"
        info: dict[str, Any] = {f"reward/{k}": np.where(terminated, 0.0, v) for k, v in terms.items()}
        info["reward/failure"] = np.where(terminated, FAILURE_REWARD, 0.0)
        info.update(extra)
        info["failed"] = terminated.copy()
        info["failure_reason"] = reason
        info["newton_iters"] = c.iters
        info["unconverged_steps"] = c.unconv
        info["retried_steps"] = c.retries
        info["episode_step"] = self.step_count.copy()
        self.last_step_seconds = time.perf_counter() - c.t0
        for o in self.observers:
            o.on_step(self, reward, terminated, truncated, info)
        return obs, reward, terminated, truncated, info

    # ---------------------------------------------------------------- observation
    def observe(self) -> np.ndarray:
        """Current observations (B, obs_dim) float32 (no state change)."""
        return self._concat(self._fields())

    def _concat(self, fields: dict[str, np.ndarray]) -> np.ndarray:
        B = self.envs
        out = np.empty((B, self.obs_dim), dtype=np.float32)
        i = 0
        for name, n in self.obs_fields:
            v = fields[name]
            dst = out[:, i:i + n]
            if v.ndim == 2:
                dst[...] = v
            else:
                view = dst.view()
                view.shape = v.shape          # a view (raises instead of silently copying)
                view[...] = v
            i += n
        np.nan_to_num(out, copy=False, nan=0.0, posinf=OBS_LIMIT, neginf=-OBS_LIMIT)
        np.clip(out, -OBS_LIMIT, OBS_LIMIT, out=out)
        return out

    def node_fields(self) -> dict[str, np.ndarray]:
        """``state_pos`` / ``state_vel`` (B, 10, D) [m], [m/s] of the observed nodes; D = 2 (x, z) in 2D.

        Views into ``state.dof`` / ``state.dof_vel`` (3D dof = [x, y, z, theta], 2D dof = [x, z]).
        """
        dof, vel = self.state.dof, self.state.dof_vel
        if self.planar:
            return {"state_pos": dof[:, self._nodes], "state_vel": vel[:, self._nodes]}
        return {"state_pos": dof[:, self._nodes, :3], "state_vel": vel[:, self._nodes, :3]}

    def tip_position(self) -> np.ndarray:
        """(B, 3) [m] (B, 2) in 2D - the tip node's position."""
        tip = self.state.dof[:, -1]
        return tip if self.planar else tip[:, :3]

    # ---------------------------------------------------------------- hooks
    def _reset_task(self, idx: np.ndarray) -> None:  # pragma: no cover - overridden
        pass

    def _post_step(self) -> None:
        pass

    def _fields(self) -> dict[str, np.ndarray]:  # pragma: no cover - overridden
        raise NotImplementedError

    def _reward(self, fields) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
        raise NotImplementedError  # pragma: no cover

    def reach_terms(self, fields: dict[str, np.ndarray], target: np.ndarray):
        """The reaching tasks' ``_reward`` (docs/tasks.md): the reward of the tip's distance to ``target`` (B, D),
        its terms and the distance."""
        d = self.obs_tip_distance(fields, target)
        r, terms = reach_reward(d)
        return r, terms, {"tip_distance": d}

    # ---------------------------------------------------------------- misc
    def obs_tip_distance(self, fields: dict[str, np.ndarray], target: np.ndarray) -> np.ndarray:
        """(B,) tip-to-target distance [m] computed from the float32 observation values (as the reference)."""
        D = 2 if self.planar else 3
        sp = fields["state_pos"]
        tip = np.asarray(sp[:, -1] if sp.ndim == 3 else sp[:, -D:], np.float32)
        return self._distance(tip, np.asarray(target, np.float32))

    @staticmethod
    def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        diff = np.asarray(a, np.float64) - np.asarray(b, np.float64)
        s = diff[:, 0] * diff[:, 0]
        for k in range(1, diff.shape[1]):
            s = s + diff[:, k] * diff[:, k]
        return np.sqrt(s)

    def close(self) -> None:
        pass

