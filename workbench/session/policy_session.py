"""A task episode driven by a policy (or by hand) one *sim* step at a time, so the page shows
every sim step; the episode is the task's own (``BatchedTask.begin_step`` / ``sim_step`` / ``end_step``, the
calls ``BatchedTask.step`` makes), so rewards, terminations and info are those of training.

The session owns a batched task core with B = 1 (``policies.tasks``); the workbench draws that core's
simulator/state/control (``LiveSim.adopt``) and the core steps it. Per control step:

* policy: ``action = policy.predict(obs)`` begins the control step (the converter's increment is ramped over
  its sim steps);
* by hand: the control step begins without an action; before each sim step the teleop's absolute (κ1, κ2,
  twist) per control point become the converter's K/T and the simulator holds ``converter.natural_values()``
  (a take-over in the middle of a policy's control step stops its increment there; a hand-back continues it);
  the episode, target and reward go on.

After the last sim step of a control step the core ends it (post-step hook, observation, reward + terms,
termination/truncation, docs/tasks.md §3.3); the next control step of a finished episode resets it.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from policies.learning import PRETRAINED
from sim.scene import CapsuleSpec
from workbench.session.obstacles import edits_from_spec

_SKIP = {"sim", "model", "state", "ctrl"}  # owned by LiveSim snapshots


def task_names() -> list[str]:
    from policies.tasks import TASKS

    return list(TASKS)


def shipped_policies(task: str | None = None) -> list[Path]:
    """Policy zips in policies/pretrained (those made for ``task`` when given)."""
    if not PRETRAINED.is_dir():
        return []
    out = []
    for p in sorted(PRETRAINED.glob("*.zip")):
        if task is None or policy_task(p) in (None, task, _task_id(task)):
            out.append(p)
    return out


def policy_task(path: Path) -> str | None:
    try:
        from policies.learning import read_policy_meta

        return read_policy_meta(path).get("task")
    except Exception:  # noqa: BLE001 - unreadable: listed, fails on load with a clear message
        return None


def _task_id(task: str) -> str:
    from policies.tasks import gym_task_id

    return gym_task_id(task)


def load_for(policy: str | Path, core, task: str):
    """The policy driving ``core``: "zero" / "random", or the policy loaded from a zip (its observation and action
    sizes must fit the task's; ``PolicyLoadError`` otherwise)."""
    if str(policy) in ("zero", "random"):
        return str(policy)
    from policies.learning import PolicyLoadError, load_policy

    pol, _meta = load_policy(policy)
    shape = tuple(pol.observation_space.shape), tuple(pol.action_space.shape)
    if shape != ((core.obs_dim,), (core.action_dim,)):
        raise PolicyLoadError(f"{policy} does not fit task {task!r}: policy obs/action {shape}, "
                              f"task ({core.obs_dim},)/({core.action_dim},)")
    return pol


def act(policy, obs: np.ndarray, action_dim: int, rng: np.random.Generator, deterministic: bool = True) -> np.ndarray:
    """Actions (B, action_dim) in [-1, 1] for observations (B, obs_dim) of ``policy`` (``load_for``)."""
    B = len(obs)
    if isinstance(policy, str):
        if policy == "random":
            return rng.uniform(-1, 1, (B, action_dim)).astype(np.float32)
        return np.zeros((B, action_dim), np.float32)
    a, _ = policy.predict(obs, deterministic=deterministic)
    return np.asarray(a, np.float32).reshape(B, -1)


class PolicySession:
    """One task (B = 1) plus a policy.

    Args:
        task: short task name or gymnasium id.
        policy: path of a policy zip, or "zero" (no action) / "random".
        seed: episode seed; deterministic: use the policy's mean action.
    """

    def __init__(self, task: str, policy: str | Path = "zero", *, seed: int = 0, deterministic: bool = True):
        from policies.tasks import TASK_SPECS, TASKS, gym_task_id

        self.task_id = gym_task_id(task)
        self.task = next((k for k, v in TASKS.items() if v == self.task_id), self.task_id)
        _env_cls, core_cls, cfg_fn = TASK_SPECS[self.task_id].load()
        self.core = core_cls(cfg_fn(), envs=1, seed=seed)
        self.deterministic = deterministic
        self.name = Path(policy).stem if str(policy) not in ("zero", "random") else str(policy)
        self._rng = np.random.default_rng(seed)
        self.source, self.seed = str(policy), seed  # what was loaded (a restart on the same scene reuses both)
        self.policy = load_for(policy, self.core, self.task)
        self.substeps = int(self.core.config.substeps)
        self.obstacles_version = 0  # bumped when the task re-places its obstacles (new episode, rewind)
        self._start_episode()

    # ------------------------------------------------------------------ episode
    def _start_episode(self) -> None:
        self.obs = self.core.reset()   # also drops a control step left unfinished
        self.obstacles_version += 1
        self.done = False
        self.episode_return = 0.0
        self.scalars: dict[str, float] = {}

    def reset(self, live) -> None:
        """New episode (called by ``Workbench.reset``)."""
        self._start_episode()

    def scene_spec(self):
        """None: the session's simulator is adopted directly (see ``Workbench.start_policy``)."""
        return None

    # ------------------------------------------------------------------ stepping
    def _action(self) -> np.ndarray:
        return act(self.policy, self.obs, self.core.action_dim, self._rng, self.deterministic)

    def sim_step(self, live=None, *, hand=None) -> dict:
        """One sim step of the episode (``live``: the workbench's ``LiveSim`` wrapping the core's simulator, which
        times the step and keeps its stats; None: headless). ``hand``: the teleop driving instead of the policy.
        Begins a control step (a new episode first when the last one ended) before its first sim step and ends it
        after its last; returns the scalars of the latest ended control step."""
        core = self.core
        if not core.step_in_progress:
            if self.done:
                self._start_episode()
            core.begin_step(None if hand is not None else self._action())
        if hand is not None:
            self.set_accumulated(hand.values[:, :2], hand.values[:, 2])
            kappa, tau = core.converter.natural_values()
            rest = getattr(live, "rest_ctrl", None)
            core.ctrl.kappa_bar[...] = kappa + (0.0 if rest is None else rest.kappa_bar)
            core.ctrl.tau_bar[...] = tau + (0.0 if rest is None else rest.tau_bar)

        def one_step():
            return core.sim_step(increment=hand is None)

        if live is None:
            one_step()
        else:
            live.step(one_step)
        if core.sim_steps_taken < self.substeps:
            return dict(self.scalars)
        self.obs, reward, terminated, truncated, info = core.end_step()
        r = float(reward[0])
        self.done = bool(terminated[0] or truncated[0])
        self.episode_return += r
        sc = {"reward": r, "return": self.episode_return, "episode_step": float(core.step_count[0])}
        for k, v in info.items():
            if k.startswith("reward/"):  # the task's terms and its failure reward, as the recordings hold them
                sc[f"r_{k[len('reward/'):]}"] = float(v[0])
        d = info.get("tip_distance")
        if d is not None:
            sc["tip_error"] = float(np.asarray(d)[0])
        o = info.get("orientation_distance")
        if o is not None:
            sc["ori_error"] = float(np.asarray(o)[0])
        self.scalars = sc
        return dict(sc)

    @property
    def planar(self) -> bool:
        """A 2-D task: one in-plane bending component per control point, no twist (docs/tasks.md §2.2)."""
        cfg = self.core.converter.cfg
        return cfg.n_components == 1 and not cfg.has_twist

    # ------------------------------------------------------------------ hand control
    def accumulated(self) -> tuple[np.ndarray, np.ndarray]:
        """(K (5, 2), T (5,)) the converter's accumulated curvature/twist per control point."""
        conv = self.core.converter
        K = np.zeros((conv.cfg.n_points, 2))
        K[:, : conv.cfg.n_components] = conv.K[0]
        return K, np.asarray(conv.T[0], dtype=np.float64).copy()

    def set_accumulated(self, K: np.ndarray, T: np.ndarray) -> None:
        conv = self.core.converter
        cfg = conv.cfg
        conv.K[0] = np.clip(np.asarray(K)[:, : cfg.n_components], -cfg.kappa_limit, cfg.kappa_limit)
        if cfg.has_twist:
            conv.T[0] = np.clip(np.asarray(T), -cfg.twist_limit, cfg.twist_limit)

    # ------------------------------------------------------------------ display
    def targets(self) -> np.ndarray | None:
        tgt = getattr(self.core, "target", None)
        pos = getattr(tgt, "pos", None) if tgt is not None else None
        if pos is None:
            pos = getattr(self.core, "target_pos", None)
        if pos is None:
            return None
        p = np.asarray(pos, dtype=np.float64).reshape(-1)
        if p.size == 2:  # 2D tasks: (x, z)
            p = np.array([p[0], 0.0, p[1]])
        return p[:3].reshape(1, 3)

    def target_wxyz(self) -> np.ndarray | None:
        q = getattr(self.core, "target_quat", None)
        if q is None:
            return None
        q = np.asarray(q, dtype=np.float64).reshape(-1)[:4]  # x y z w
        return np.array([q[3], q[0], q[1], q[2]])

    def display_obstacles(self) -> list | None:
        """Obstacles the task placed for this episode (3D random fence), or None (scene obstacles)."""
        fences = getattr(self.core, "fences", None)
        if fences is None:
            return None

        r = float(self.core.config.fence.radius)
        caps = tuple(CapsuleSpec(start=tuple(map(float, a)), end=tuple(map(float, b)), radius=r, name=f"fence {i}")
                     for i, (a, b) in enumerate(np.asarray(fences[0], dtype=np.float64)))

        class _Spec:
            obstacles = caps

        return edits_from_spec(_Spec)

    # ------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict:
        core = {k: v for k, v in vars(self.core).items() if k not in _SKIP}
        own = {k: v for k, v in vars(self).items() if k not in ("core", "policy")}
        return copy.deepcopy({"core": core, "own": own})

    def restore(self, snap: dict) -> None:
        snap = copy.deepcopy(snap)
        for k, v in snap["core"].items():
            setattr(self.core, k, v)
        version = self.obstacles_version
        for k, v in snap["own"].items():
            setattr(self, k, v)
        self.obstacles_version = version + 1
